"""The in-process harness (ros/harness.py): stepped and background use, timeouts, closing."""

from __future__ import annotations

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('sensor_msgs.msg')

from image_fixtures import shifted, texture
from node_harness import double_model_file
from ros_helpers import DOMAIN_ID, configure_this_process

from initsel_ros.errors import InitselError
from initsel_ros.policy import Reason
from initsel_ros.ros.harness import HarnessTimeoutError, NodeHarness
from initsel_ros.status import FrameStatus

configure_this_process()


def test_a_background_harness_records_every_status_with_its_arrival(tmp_path):
    parameters = {'model_file': double_model_file(tmp_path), 'mode': 'continuous'}
    with NodeHarness(parameters, domain_id=DOMAIN_ID, namespace='/harness_bg') as h:
        assert h.start() is h and h.background
        img = texture(30)
        for k in range(3):
            h.publish(h.image_message(shifted(img, k, 0.0), 2.0 + k / 30))
            assert h.wait_for(lambda n=k: len(h.statuses) > n, 20.0)
        with h.lock:
            statuses, arrivals = list(h.statuses), list(h.status_arrivals)
        context = h.context
    assert all(isinstance(s, FrameStatus) for s in statuses) and len(arrivals) == 3
    assert [s.reason for s in statuses] == [
        Reason.NEW_REFERENCE,
        Reason.NO_MODEL_FIRED,
        Reason.NO_MODEL_FIRED,
    ]
    assert [s.stamp for s in statuses] == pytest.approx([2.0, 2.0 + 1 / 30, 2.0 + 2 / 30])
    assert not context.ok()  # a private context is shut down with the harness


def test_a_stepped_harness_sends_resets_and_times_out_with_one_error(tmp_path):
    with NodeHarness(
        {'model_file': double_model_file(tmp_path)}, domain_id=DOMAIN_ID, namespace='/harness_step'
    ) as h:
        img = texture(31)
        assert h.send_array(img, 1.0).new_reference
        assert h.send_array(shifted(img, 1.0, 0.0), 1.033).frames_since_reference == 1
        assert h.reset().success
        assert h.send_array(shifted(img, 2.0, 0.0), 1.066).reason is Reason.NEW_REFERENCE
        with pytest.raises(HarnessTimeoutError, match='waiting for nothing') as caught:
            h.wait_until(lambda: False, timeout=0.2, what='nothing')
        assert isinstance(caught.value, InitselError) and isinstance(caught.value, TimeoutError)
