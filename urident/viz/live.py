"""Live view of a running session: :class:`LiveStreamer`.

The control loop calls :meth:`LiveStreamer.push` once per cycle (500 Hz). ``push`` only counts
the sample and does a ``put_nowait`` of a small tuple into a bounded queue; when the queue is full
the sample is dropped and counted (``dropped``), so the caller never blocks. A consumer -- a
separate process (default, ``backend="process"``) or a daemon thread (``backend="thread"``) --
takes samples in batches of about ``batch_interval_s`` (40 ms) and, for each batch:

* measured and predicted torque from :class:`urident.ident.StreamPredictor`, the one prediction
  path in its causal mode (parameters: nominal, a 78- or base-vector, or identified ones): the
  parameters' drive gains × current, and q̈ by the parameters' acceleration filter run forwards
  only (lag ≈ 16 ms at 10 Hz; a running session has no future samples), friction states carried
  from batch to batch;
* residual, tracking error ``target_q − q`` (when given), running RMS and e_N
  (:class:`urident.ident.RunningMetrics`);
* the robot's pose (capsules and skeleton from ``frame_poses``) at ``pose_rate_hz`` (30 Hz);
* run status: ``status/samples`` (pushed so far), ``status/late_cycles``, ``status/dropped``
  (visualisation samples lost), events and the abort reason as ``status/events`` text log
  entries and a ``status/summary`` document at the end.

Entity paths are those of the post-hoc view (``torque/{joint}/measured|predicted|residual``,
``robot/...``, ``metrics/...``) plus ``tracking/{joint}`` and ``status/...``.

When no viewer can be spawned or reached, the streamer falls back to ``fallback_save`` (an .rrd
file) if given, else disables itself; either way it prints one warning line and the session goes
on (``strict=True`` raises :class:`~urident.viz.recording.ViewerUnavailable` instead).

Why a process by default: a consumer *thread* shares the GIL, and Python hands the GIL back only
every ``sys.getswitchinterval()`` (5 ms), so a 500 Hz loop in the same process sees delays of up
to ~5-8 ms while the consumer computes (measured here: worst ``push`` 7.6 ms and ~20 % late
cycles with a thread, against 0.5 ms and no more late cycles than without any view with a
process). The process backend uses the ``spawn`` start method (about 1-2 s to start), so a script
that creates the streamer needs the usual ``if __name__ == "__main__":`` guard; ``samples`` must
be picklable.

Pass fresh objects to ``push`` (rtde's ``getActualQ()`` lists are); a numpy buffer the caller
rewrites in place would be read later by the consumer.
"""

from __future__ import annotations

import multiprocessing
import queue as queue_mod
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from urident.model.robot import RobotSpec
from urident.viz.robot3d import DEFAULT_POSE_RATE_HZ

_STOP = "__stop__"
_EVENT = "__event__"


@dataclass(frozen=True)
class LiveStats:
    """What :meth:`LiveStreamer.close` reports."""

    pushed: int          # samples given to push()
    dropped: int         # samples dropped because the consumer was behind (or it failed)
    processed: int       # samples the consumer logged
    error: str | None    # the consumer's failure, if any (the run itself is unaffected)
    sink: str            # where the view went ("disabled" when it could not be opened)


def _warn(message: str) -> None:
    print(f"urident: warning: {message}", file=sys.stderr)


# --------------------------------------------------------------------------- consumer side
class _Consumer:
    """Turns batches of samples into Rerun data. Runs in the consumer thread or process."""

    def __init__(self, spec: RobotSpec, params: Any, sink: dict[str, Any], app_id: str,
                 prefix: str, pose_rate_hz: float, window_s: float | None):
        from urident.ident import RunningMetrics, StreamPredictor
        from urident.viz.blueprint import live_blueprint
        from urident.viz.recording import open_recording
        from urident.viz.robot3d import log_robot_static
        from urident.viz.torque_views import log_series_style

        self.spec = spec
        self.predictor = StreamPredictor(params, spec)
        self.running = RunningMetrics()
        self.prefix = prefix
        self.pose_rate_hz = pose_rate_hz
        self.joints = spec.joint_names
        self.rec = open_recording(app_id, blueprint=live_blueprint(prefix, self.joints,
                                                                   window_s=window_s), **sink)
        log_series_style(self.rec, prefix, self.joints)
        log_robot_static(self.rec, spec)
        self.processed = 0
        self.last_seq = 0
        self.last_t: float | None = None
        self.late_cycles = 0
        self._pose_bin: float | None = None

    def samples(self, items: list[tuple]) -> None:
        from urident.viz.robot3d import log_robot_motion
        from urident.viz.torque_views import log_joint_series, log_metrics, log_torque_comparison

        if self.last_t is not None:  # keep time strictly increasing
            items = [s for s in items if s[0] > self.last_t]
        if not items:
            return
        t = np.array([s[0] for s in items], dtype=float)
        keep = np.ones(len(t), dtype=bool)
        keep[1:] = np.diff(t) > 0
        if not keep.all():
            items = [s for s, k in zip(items, keep) if k]
            t = t[keep]
        q = np.array([s[1] for s in items], dtype=float).reshape(-1, 6)
        qd = np.array([s[2] for s in items], dtype=float).reshape(-1, 6)
        current = np.array([s[3] for s in items], dtype=float).reshape(-1, 6)
        _, tau_m, tau_p = self.predictor.update(t, q, qd, current)
        rec = self.rec
        log_torque_comparison(rec, t, tau_m, tau_p, self.prefix, self.joints, style=False)
        with_target = [k for k, s in enumerate(items) if s[4] is not None]
        if with_target:
            target = np.array([items[k][4] for k in with_target], dtype=float).reshape(-1, 6)
            log_joint_series(rec, "tracking", t[with_target], target - q[with_target], self.joints)
        # poses at pose_rate_hz: the first sample of each new 1/rate bin
        if self.pose_rate_hz and self.pose_rate_hz > 0:
            bins = np.floor(t * self.pose_rate_hz)
            prev = np.concatenate([[np.nan if self._pose_bin is None else self._pose_bin], bins[:-1]])
            idx = np.flatnonzero(bins != prev)
            self._pose_bin = float(bins[-1])
        else:
            idx = np.arange(len(t))
        if len(idx):
            log_robot_motion(rec, self.spec, t[idx], q[idx], rate_hz=None, static_parts=False)
        # status and running metrics at the batch's last sample
        self.processed += len(t)
        self.last_seq = int(items[-1][6])
        self.late_cycles = int(items[-1][5])
        self.last_t = float(t[-1])
        self.running.add(tau_m - tau_p)
        metrics = {f"rms/{j}": float(v) for j, v in zip(self.joints, self.running.rms)}
        metrics["e_N"] = self.running.e_n
        log_metrics(rec, metrics, prefix="metrics", t=self.last_t)
        log_metrics(rec, {"samples": self.last_seq, "late_cycles": self.late_cycles,
                          "dropped": self.last_seq - self.processed}, prefix="status", t=self.last_t)

    def event(self, text: str, level: str) -> None:
        from urident.viz.torque_views import log_event

        log_event(self.rec, text, level, t=self.last_t if self.last_t is not None else None)

    def finish(self, abort_reason: str | None, pushed: int, dropped: int) -> None:
        from urident.viz.recording import close_recording
        from urident.viz.torque_views import log_event, log_text

        t = self.last_t
        if abort_reason:
            log_event(self.rec, f"run aborted: {abort_reason}", "ERROR", t=t)
        else:
            log_event(self.rec, "run finished", "INFO", t=t)
        text = ["# Run status", "",
                f"- result: {'**aborted**: ' + abort_reason if abort_reason else 'completed'}",
                f"- samples pushed: {pushed}", f"- samples shown: {self.processed}",
                f"- samples dropped by the view: {dropped}", f"- late cycles: {self.late_cycles}"]
        log_text(self.rec, "status/summary", "\n".join(text) + "\n")
        close_recording(self.rec)


def _consume(q, closing, consumer_factory: Callable[[], _Consumer], batch_interval_s: float,
             report: Callable[[dict], None], ready: Callable[[str | None], None]) -> None:
    """The consumer loop (thread or process): batch, process, stop on the sentinel or when
    ``closing`` is set and the queue is empty. Failures are reported, never raised."""
    try:
        consumer = consumer_factory()
    except Exception as exc:  # noqa: BLE001
        ready(f"{type(exc).__name__}: {exc}")
        return
    ready(None)
    error: str | None = None
    stop: tuple | None = None
    while stop is None:
        try:
            first = q.get(timeout=0.1)
        except queue_mod.Empty:
            if closing.is_set():
                break
            continue
        time.sleep(batch_interval_s)  # let a batch accumulate: fewer, larger Rerun calls
        batch = [first]
        while True:
            try:
                batch.append(q.get_nowait())
            except queue_mod.Empty:
                break
        samples: list[tuple] = []
        for item in batch:
            if item[0] == _STOP:
                stop = item
                break
            if item[0] == _EVENT:
                error = _run_step(consumer.samples, samples, error)
                samples = []
                error = _run_step(lambda args: consumer.event(*args), item[1:], error)
            else:
                samples.append(item)
        if samples:
            error = _run_step(consumer.samples, samples, error)
    abort_reason, pushed, dropped = (stop[1], stop[2], stop[3]) if stop else (None, 0, 0)
    try:
        consumer.finish(abort_reason, pushed, dropped)
    except Exception as exc:  # noqa: BLE001
        error = error or f"{type(exc).__name__}: {exc}"
    report({"processed": consumer.processed, "error": error})


def _run_step(fn: Callable, arg: Any, error: str | None) -> str | None:
    """Run one consumer step unless a previous one failed; keep the first failure."""
    if error is not None or (isinstance(arg, list) and not arg):
        return error
    try:
        fn(arg)
    except Exception as exc:  # noqa: BLE001 - the view must never take the run down
        return f"{type(exc).__name__}: {exc}"
    return None


def _process_main(q, closing, results, config: dict) -> None:
    """Entry point of the consumer process."""
    batch_interval_s = float(config.pop("batch_interval_s"))
    _consume(q, closing, lambda: _Consumer(**config), batch_interval_s,
             lambda r: results.put(("done", r)), lambda err: results.put(("ready", err)))


# --------------------------------------------------------------------------- caller side
class LiveStreamer:
    """Stream a running session to Rerun without ever blocking the control loop.

    ``params``: None (nominal), a 78-vector, a base-parameter vector, or identified parameters
    (:class:`urident.ident.IdentifiedModel`, e.g. ``load_prediction_params``). Sink: exactly one of
    ``save`` (``.rrd`` path), ``spawn=True``, ``connect`` (gRPC URL, ``""`` = default).
    ``queue_size`` bounds the queue (1000 ≈ 2 s at 500 Hz). Use as a context manager or call
    :meth:`close`."""

    def __init__(
        self,
        spec: RobotSpec,
        params: Any = None,
        *,
        save: str | Path | None = None,
        spawn: bool = False,
        connect: str | None = None,
        fallback_save: str | Path | None = None,
        strict: bool = False,
        backend: str = "process",
        queue_size: int = 1000,
        pose_rate_hz: float = DEFAULT_POSE_RATE_HZ,
        batch_interval_s: float = 0.04,
        window_s: float | None = 10.0,
        prefix: str = "torque",
        app_id: str = "urident_run",
        start_timeout_s: float = 30.0,
        warn: Callable[[str], None] = _warn,
    ) -> None:
        if backend not in ("thread", "process"):
            raise ValueError(f"backend must be 'thread' or 'process', not {backend!r}")
        if queue_size < 1:
            raise ValueError(f"queue_size must be positive, got {queue_size}")
        self.pushed = 0
        self.dropped = 0
        self.disabled_reason: str | None = None
        self._closed = False
        self._stats: LiveStats | None = None
        self._warn = warn
        self._backend = backend
        sink = self._resolve_sink(save, spawn, connect, fallback_save, strict)
        if sink is None:
            self.sink = "disabled"
            self._q = None
            return
        from urident.ident.prediction import as_parameters

        params = as_parameters(spec, params)  # errors (bad parameter vector) reach the caller
        if params.model.uses_temperature:   # the streamed samples carry no joint temperature
            from urident.errors import ConfigError

            raise ConfigError("the live view cannot predict a model with joint-temperature friction terms "
                              "(tempvisc/tempcoul): view the log afterwards (urident view LOG --params ...)")
        config = dict(spec=spec, params=params, sink=sink, app_id=app_id, prefix=prefix,
                      pose_rate_hz=pose_rate_hz, window_s=window_s)
        if backend == "thread":
            self._q = queue_mod.Queue(maxsize=queue_size)
            self._closing = threading.Event()
            self._result: dict = {}
            self._ready = threading.Event()
            self._ready_error: list[str | None] = [None]

            def ready(err: str | None) -> None:
                self._ready_error[0] = err
                self._ready.set()

            self._worker = threading.Thread(
                target=_consume, name="urident-live-view", daemon=True,
                args=(self._q, self._closing, lambda: _Consumer(**config), batch_interval_s,
                      self._result.update, ready))
            self._worker.start()
            self._ready.wait(start_timeout_s)
            err = self._ready_error[0] if self._ready.is_set() else "consumer did not start in time"
        else:
            ctx = multiprocessing.get_context("spawn")
            self._q = ctx.Queue(maxsize=queue_size)
            self._closing = ctx.Event()
            self._results = ctx.Queue()
            config["batch_interval_s"] = batch_interval_s
            self._worker = ctx.Process(target=_process_main, name="urident-live-view", daemon=True,
                                       args=(self._q, self._closing, self._results, config))
            self._worker.start()
            err = "consumer process did not start in time"
            deadline = time.monotonic() + start_timeout_s
            while time.monotonic() < deadline:
                try:
                    kind, err = self._results.get(timeout=0.2)
                    break
                except queue_mod.Empty:
                    if not self._worker.is_alive():
                        err = f"consumer process exited with code {self._worker.exitcode}"
                        break
        if err is not None:
            self._disable(f"live view could not start ({err}); the run goes on without it")
            return
        self.sink = str(sink.get("save") or ("spawned viewer" if sink.get("spawn")
                                             else f"viewer at {sink.get('connect') or 'default'}"))
        self._put = self._q.put_nowait

    # ------------------------------------------------------------------ setup helpers
    def _resolve_sink(self, save, spawn, connect, fallback_save, strict) -> dict | None:
        from urident.viz.recording import DEFAULT_URL, ViewerUnavailable, unreachable_reason, \
            viewer_unavailable_reason

        if sum((save is not None, bool(spawn), connect is not None)) != 1:
            raise ValueError("LiveStreamer needs exactly one sink: save=PATH, spawn=True or connect=URL")
        if save is not None:
            return {"save": str(save)}
        if spawn:
            reason = viewer_unavailable_reason()
            what = "cannot spawn a Rerun viewer"
        else:
            reason = unreachable_reason(connect or DEFAULT_URL)
            what = f"cannot reach a Rerun viewer at {connect or DEFAULT_URL}"
        if reason is None:
            return {"spawn": True} if spawn else {"connect": connect}
        if strict:
            raise ViewerUnavailable(f"{what}: {reason}; use --save OUT.rrd instead")
        if fallback_save is not None:
            self._warn(f"{what}: {reason}; saving the live view to {fallback_save} instead")
            return {"save": str(fallback_save)}
        self.disabled_reason = f"{what}: {reason}"
        self._warn(f"{what}: {reason}; live view disabled (the run goes on)")
        return None

    def _disable(self, message: str) -> None:
        self.disabled_reason = message
        self.sink = "disabled"
        self._warn(message)
        self._closing.set()
        self._q = None

    @property
    def enabled(self) -> bool:
        return self._q is not None and not self._closed

    # ------------------------------------------------------------------ control-loop side
    def push(self, t, q=None, qd=None, current=None, target_q=None, late_cycles: int = 0) -> bool:
        """Queue one sample (t [s], q [rad], qd [rad/s], current [A], optional target_q [rad],
        the session's late-cycle count so far). ``push(state, target_q)`` with an RTDE state
        mapping (``timestamp``, ``actual_q``, ``actual_qd``, ``actual_current``, optional
        ``late_cycles``) works too. Never blocks; returns False when the sample was dropped
        (consumer behind, or the view disabled/closed)."""
        self.pushed += 1
        if self._q is None or self._closed:
            return False
        if isinstance(t, Mapping):
            state = t
            target_q = q if q is not None else target_q
            t, q, qd, current = (state["timestamp"], state["actual_q"], state["actual_qd"],
                                 state["actual_current"])
            late_cycles = state.get("late_cycles", late_cycles)
        try:
            self._put((t, q, qd, current, target_q, late_cycles, self.pushed))
        except queue_mod.Full:
            self.dropped += 1
            return False
        return True

    def event(self, text: str, level: str = "INFO") -> bool:
        """A status line (INFO, WARN, ERROR) in the ``status/events`` log. Never blocks."""
        if self._q is None or self._closed:
            return False
        try:
            self._put((_EVENT, str(text), str(level)))
        except queue_mod.Full:
            return False
        return True

    # ------------------------------------------------------------------ shutdown
    def close(self, abort_reason: str | None = None, timeout_s: float = 10.0) -> LiveStats:
        """Log the final status (``abort_reason`` as an ERROR event), flush the sink and join the
        consumer, waiting at most about ``timeout_s``. Idempotent; never raises."""
        if self._stats is not None:
            return self._stats
        self._closed = True
        processed, error = 0, None
        if self._q is not None:
            reason = None if abort_reason is None else " ".join(str(abort_reason).split())
            deadline = time.monotonic() + timeout_s
            try:
                self._q.put((_STOP, reason, self.pushed, self.dropped), timeout=timeout_s / 2)
            except queue_mod.Full:
                error = "view queue stayed full at close; final status not logged"
            self._closing.set()
            result = self._join(max(deadline - time.monotonic(), 0.1))
            if result is None:
                error = error or f"live view did not finish within {timeout_s:g} s"
            else:
                processed, error = result["processed"], error or result["error"]
        self._stats = LiveStats(self.pushed, self.dropped, processed, error,
                                getattr(self, "sink", "disabled"))
        if error:
            self._warn(f"live view: {error}")
        return self._stats

    def _join(self, timeout_s: float) -> dict | None:
        if self._backend == "thread":
            self._worker.join(timeout_s)
            return None if self._worker.is_alive() else dict(self._result)
        try:
            kind, result = self._results.get(timeout=timeout_s)
        except queue_mod.Empty:
            result = None
        self._worker.join(2.0)
        self._q.cancel_join_thread()  # never hang at exit on samples nobody will read
        if self._worker.is_alive():
            self._worker.terminate()
            self._worker.join(2.0)
        return result

    @property
    def stats(self) -> LiveStats:
        return self._stats or LiveStats(self.pushed, self.dropped, 0, None,
                                        getattr(self, "sink", "disabled"))

    def __enter__(self) -> "LiveStreamer":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        reason = None if exc_type is None else (f"{exc_type.__name__}: {exc}" if str(exc)
                                                else exc_type.__name__)
        self.close(abort_reason=reason)
