"""The shipped RViz 2 layout matches the node's topics and default reference frame."""

from __future__ import annotations

from pathlib import Path

import yaml

from initsel_ros.ros.params import load_params_file

CONFIG = Path(__file__).resolve().parent.parent / 'config'


def _displays(tree: list[dict]) -> list[dict]:
    out = []
    for d in tree:
        out.append(d)
        out.extend(_displays(d.get('Displays', [])))
    return out


def test_rviz_layout_shows_the_node_topics_in_the_reference_frame():
    rviz = yaml.safe_load((CONFIG / 'initsel.rviz').read_text())
    params = load_params_file(CONFIG / 'selector.yaml')  # any node-section key
    manager = rviz['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == params['reference_frame_id']
    topics = {d['Topic']['Value']: d for d in _displays(manager['Displays']) if 'Topic' in d}
    assert topics['/image_raw']['Class'] == 'rviz_default_plugins/Image'
    assert topics['/selector/debug_image']['Class'] == 'rviz_default_plugins/Image'
    assert topics['/init/points']['Class'] == 'rviz_default_plugins/PointCloud2'
    assert topics['/init/pose']['Class'] == 'rviz_default_plugins/Pose'
    for latched in ('/init/points', '/init/pose'):  # the node latches init/*
        assert topics[latched]['Topic']['Durability Policy'] == 'Transient Local'
        assert topics[latched]['Topic']['Reliability Policy'] == 'Reliable'
    for image in ('/image_raw', '/selector/debug_image'):  # matches any publisher
        assert topics[image]['Topic']['Reliability Policy'] == 'Best Effort'
