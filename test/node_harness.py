"""Glue of the in-process node tests around :class:`initsel_ros.ros.harness.NodeHarness`.

No launch, no subprocesses: a private rclpy context on a private DDS domain, one namespace per
harness. Frames are fed one at a time and each waits for its ``~/status``, so nothing is
dropped and every frame is accounted for. Test modules wrap :func:`ros_context` and
:func:`harnesses` in fixtures.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Iterator

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from ros_helpers import DOMAIN_ID, configure_this_process

from initsel_ros.ros.harness import TIMEOUT_S, NodeHarness
from initsel_ros.status import FrameStatus

configure_this_process()
_namespaces = itertools.count()

__all__ = ['TIMEOUT_S', 'as_sequence', 'double_model_file', 'harnesses', 'play', 'ros_context']


def ros_context() -> Iterator[rclpy.Context]:
    """A private rclpy context on this run's domain (body of a module-scoped fixture)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def make_harness(context: rclpy.Context, **parameters: object) -> NodeHarness:
    """A stepped harness in a namespace of its own; ``a__b=v`` sets parameter ``a.b``."""
    return NodeHarness(
        {k.replace('__', '.'): v for k, v in parameters.items()},
        context=context,
        namespace=f'/itest{next(_namespaces)}',
        client_name='initsel_test_client',
    )


def harnesses(context: rclpy.Context) -> Iterator[Callable[..., NodeHarness]]:
    """A factory of harnesses closed afterwards (body of a function fixture)."""
    made: list[NodeHarness] = []

    def make(**parameters: object) -> NodeHarness:
        h = make_harness(context, **parameters)
        made.append(h)
        return h

    yield make
    for h in made:
        h.close()


def as_sequence(fixture_value):
    """Conftest fixtures may hand out a Sequence or a path to one."""
    if hasattr(fixture_value, 'frames'):
        return fixture_value
    from initsel_ros.datasets import open_sequence

    return open_sequence(fixture_value)


def play(
    h: NodeHarness,
    sequence,
    stamps: list[Time] | None = None,
    convert: Callable[[np.ndarray], np.ndarray] | None = None,
    until_initialized: bool = False,
) -> list[FrameStatus]:
    """Send the sequence's camera_info and frames (with ``stamps``, pixels via ``convert``)."""
    h.send_camera_info(sequence.intrinsics)
    statuses = []
    for i, frame in enumerate(sequence.frames):
        image = sequence.image(i) if convert is None else convert(sequence.image(i))
        statuses.append(h.send_array(image, frame.stamp if stamps is None else stamps[i]))
        if until_initialized and statuses[-1].method:
            break
    return statuses


def double_model_file(tmp_path) -> str:
    """A test-double model file: constant probabilities, nothing ever fires."""
    from model_fixtures import constant_models

    path = tmp_path / 'constant_models.json'
    constant_models().save(path)
    return str(path)


def hold_selector(harness: NodeHarness) -> tuple[threading.Event, threading.Event]:
    """Make the node's worker wait inside the selector: ``entered`` is set once a frame is in,
    and the frame goes on when ``release`` is set (so a test can queue frames behind it)."""
    entered, release = threading.Event(), threading.Event()
    process = harness.node._selector.process

    def slow_process(image, stamp):
        entered.set()
        assert release.wait(10.0)
        return process(image, stamp)

    harness.node._selector.process = slow_process
    return entered, release
