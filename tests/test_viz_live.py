"""The live streamer of ``urident run`` (issue 7): non-blocking push, drop counting, headless
fallback, and what ends up in the .rrd file."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from urident.model import load_robot
from urident.viz import LiveStreamer, ViewerUnavailable, read_rrd


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5e")


def _sample(k: int):
    t = 10.0 + 0.002 * k
    q = [0.3 * np.sin(t + j) for j in range(6)]
    qd = [0.3 * np.cos(t + j) for j in range(6)]
    return t, q, qd, [0.4] * 6


class _Gate:
    """Makes the one prediction path block until released: a consumer far behind the loop."""

    def __init__(self, monkeypatch):
        from urident.ident.prediction import StreamPredictor

        self.gate = threading.Event()
        inner = StreamPredictor.update

        def update(predictor, *args):
            self.gate.wait(60)
            return inner(predictor, *args)

        monkeypatch.setattr(StreamPredictor, "update", update)


def _headless(monkeypatch):
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr("sys.platform", "linux")


def test_push_never_blocks_and_counts_drops(tmp_path, spec, monkeypatch):
    model = _Gate(monkeypatch)
    out = tmp_path / "drops.rrd"
    streamer = LiveStreamer(spec, save=out, backend="thread", queue_size=50)
    n = 3000
    accepted = []

    def control_loop():
        for k in range(n):
            accepted.append(streamer.push(*_sample(k), late_cycles=0))

    loop = threading.Thread(target=control_loop)
    loop.start()
    loop.join(60)  # a hang guard only: a blocking push would never let the loop finish
    assert not loop.is_alive(), "push blocked while the consumer was stuck"
    assert len(accepted) == n
    assert streamer.dropped == accepted.count(False) > 0
    assert streamer.dropped >= n - 50 - 1000  # at most the queue and one consumer batch got in
    model.gate.set()
    stats = streamer.close(abort_reason="operator stop")
    assert stats.error is None
    assert stats.pushed == n
    assert stats.processed + stats.dropped == n

    contents = read_rrd(out)
    times, values = contents.scalars("torque/shoulder_pan/measured")
    assert len(values) == stats.processed
    (_, summary), = contents.rows("status/summary", "TextDocument:text")
    assert f"samples dropped by the view: {stats.dropped}" in summary[0]
    texts = [cell[0] for _, cell in contents.rows("status/events", "TextLog:text")]
    assert texts[-1] == "run aborted: operator stop"


def test_process_backend_streams_everything(tmp_path, spec):
    out = tmp_path / "live.rrd"
    n = 600
    with LiveStreamer(spec, save=out, queue_size=n + 10, pose_rate_hz=25.0) as streamer:
        streamer.event("trajectory started")
        for k in range(n):
            t, q, qd, current = _sample(k)
            assert streamer.push(t, q, qd, current, target_q=q, late_cycles=k // 300)
    stats = streamer.stats
    assert stats.error is None and stats.dropped == 0 and stats.processed == n

    contents = read_rrd(out)
    assert contents.has_blueprint
    for joint in spec.joint_names:
        for series in ("measured", "predicted", "residual"):
            times, values = contents.scalars(f"torque/{joint}/{series}")
            assert len(values) == n
        _, measured = contents.scalars(f"torque/{joint}/measured")
        np.testing.assert_allclose(measured, 0.4 * spec.drive_gains[spec.joint_names.index(joint)])
        _, tracking = contents.scalars(f"tracking/{joint}")
        np.testing.assert_allclose(tracking, 0.0)
        assert contents.scalars(f"metrics/rms/{joint}")[1].size > 0
    _, samples = contents.scalars("status/samples")
    _, late = contents.scalars("status/late_cycles")
    _, dropped = contents.scalars("status/dropped")
    assert samples[-1] == n and late[-1] == 1 and dropped[-1] == 0
    poses = contents.rows("robot/links", "Capsules3D:translations")
    assert 20 <= len(poses) <= 32  # 1.2 s at 25 Hz
    texts = [cell[0] for _, cell in contents.rows("status/events", "TextLog:text")]
    assert texts[0] == "trajectory started" and texts[-1] == "run finished"


def test_headless_spawn_falls_back_to_file(tmp_path, spec, monkeypatch):
    _headless(monkeypatch)
    warnings = []
    out = tmp_path / "fallback.rrd"
    streamer = LiveStreamer(spec, spawn=True, fallback_save=out, backend="thread",
                            warn=warnings.append)
    for k in range(20):
        streamer.push(*_sample(k))
    stats = streamer.close()
    assert stats.sink == str(out) and stats.processed == 20
    assert len(warnings) == 1 and "no display" in warnings[0] and str(out) in warnings[0]
    assert len(read_rrd(out).scalars("torque/elbow/predicted")[1]) == 20


def test_headless_spawn_without_fallback_disables(spec, monkeypatch):
    _headless(monkeypatch)
    warnings = []
    streamer = LiveStreamer(spec, spawn=True, warn=warnings.append)
    assert not streamer.enabled and "no display" in streamer.disabled_reason
    assert streamer.push(*_sample(0)) is False
    stats = streamer.close(abort_reason="whatever")
    assert stats.sink == "disabled" and stats.pushed == 1 and stats.error is None
    assert len(warnings) == 1 and "live view disabled" in warnings[0]
    with pytest.raises(ViewerUnavailable, match="no display"):
        LiveStreamer(spec, spawn=True, strict=True)


def test_consumer_failure_is_reported_not_raised(tmp_path, spec, monkeypatch):
    from urident.ident.prediction import StreamPredictor

    def broken(*args):
        raise RuntimeError("model exploded")

    monkeypatch.setattr(StreamPredictor, "update", broken)
    warnings = []
    streamer = LiveStreamer(spec, save=tmp_path / "broken.rrd", backend="thread",
                            warn=warnings.append)
    for k in range(10):
        streamer.push(*_sample(k))
    stats = streamer.close()
    assert "model exploded" in stats.error
    assert any("model exploded" in w for w in warnings)


def test_bad_parameter_vector_is_rejected_up_front(tmp_path, spec):
    from urident.errors import ConfigError

    with pytest.raises(ConfigError, match="got 5 values"):
        LiveStreamer(spec, np.ones(5), save=tmp_path / "x.rrd", backend="thread")


def test_push_accepts_an_rtde_state_mapping(tmp_path, spec):
    out = tmp_path / "state.rrd"
    streamer = LiveStreamer(spec, save=out, backend="thread")
    for k in range(30):
        t, q, qd, current = _sample(k)
        state = {"timestamp": t, "actual_q": np.array(q), "actual_qd": np.array(qd),
                 "actual_current": np.array(current), "safety_status_bits": 1}
        assert streamer.push(state, np.array(q) + 0.01)
    stats = streamer.close()
    assert stats.processed == 30 and stats.error is None
    _, tracking = read_rrd(out).scalars("tracking/elbow")
    np.testing.assert_allclose(tracking, 0.01)
