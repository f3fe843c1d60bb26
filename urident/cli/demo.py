"""``urident demo``: the whole pipeline on urident's simulated controller, no robot needed.

1. start the simulated controller of the robot (default UR5e; ``realistic`` preset of unmodelled
   effects) as a subprocess on a free loopback address;
2. run the identification and validation trajectories of ``experiments/`` through ``urident run``
   (checks, moveJ, servoJ at the controller's rate, recorder, live .rrd);
3. stop the controller; identify (OLS, bounded, physically consistent); validate; diagnose the
   sim-to-real gap; write a Rerun recording of the validation;
4. print a summary. Everything goes to ``logs/demo-<timestamp>/``.

``quick=True`` runs short generated trajectories instead (for tests and a first look).
"""

from __future__ import annotations

import socket
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Callable

import numpy as np

from urident.errors import UridentError

ROBOT = "ur5e"  # the default; any robot with an ident/valid pair in experiments/
EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
PORTS = (30004, 29999, 30003, 30002)
EFFECTS_PRESET = "realistic"   # the unmodelled effects the demo's simulated controller runs


@dataclass(frozen=True)
class DemoResult:
    directory: Path
    validation: dict
    gap: dict
    seconds: float
    robot: str = "UR5e"         # the arm's model name, for the summary
    injected: tuple = ()        # the effects the simulated controller ran (effects-file entries)


class DemoError(UridentError):
    """A demo step failed."""


def free_loopback_address(first: int = 100, last: int = 250) -> str:
    """A 127.0.0.x address whose controller ports are all free (earlier or parallel demos and
    tests keep theirs)."""
    start = first + int(time.time() * 1000) % (last - first)
    for k in range(last - first):
        host = f"127.0.0.{first + (start - first + k) % (last - first)}"
        sockets = []
        try:
            for port in PORTS:
                s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                sockets.append(s)
                s.bind((host, port))
            return host
        except OSError:
            continue
        finally:
            for s in sockets:
                s.close()
    raise DemoError("no free loopback address for the simulated controller (127.0.0.100-250)")


def new_run_directory(root: Path) -> Path:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    for k in range(100):
        path = root / (f"demo-{stamp}" if k == 0 else f"demo-{stamp}-{k}")
        try:
            path.mkdir(parents=True)
            return path
        except FileExistsError:
            continue
    raise DemoError(f"cannot create a new run directory under {root}")


def quick_trajectories(directory: Path, duration: float = 8.0, robot: str = ROBOT) -> tuple[Path, Path]:
    """Two short, checked rest-to-rest Fourier trajectories (different seeds)."""
    from urident.excitation import (FourierTrajectory, Limits, check_trajectory,
                                    trajectory_document, write_trajectory)
    from urident.excitation.fourier import base_frequency
    from urident.model import load_robot

    spec = load_robot(robot)
    limits = Limits.from_robot(spec)
    q0 = np.array([0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0])
    paths = []
    for name, seed in (("quick_ident.yaml", 11), ("quick_valid.yaml", 12)):
        rng = np.random.default_rng(seed)
        for scale in (0.25, 0.2, 0.15, 0.1, 0.07, 0.05, 0.035):  # small arms need the small ones
            free = rng.normal(scale=scale, size=(6, 8))
            traj = FourierTrajectory.from_free(free, base_frequency(duration), q0, duration)
            # Shift the offset so that every quick trajectory starts (and ends) at q0.
            traj = FourierTrajectory(traj.a, traj.b, traj.omega, 2 * q0 - traj.q_start, duration)
            if check_trajectory(spec, traj, spec.controller_rate_hz, limits).ok:
                break
        else:
            raise DemoError("could not generate a safe quick trajectory")
        path = directory / name
        write_trajectory(path, trajectory_document(robot, traj, limits))
        paths.append(path)
    return paths[0], paths[1]


def run_demo(root: Path = Path("logs"), quick: bool = False, seed: int = 0,
             say: Callable[[str], None] = print, robot: str = ROBOT) -> DemoResult:
    from urident import api as ur
    from urident.excitation import load_trajectory
    from urident.model import load_robot
    from urident.simcontroller.process import SimControllerProcess

    spec = load_robot(robot)
    robot = spec.name
    pair = (EXPERIMENTS / f"{robot}_ident.yaml", EXPERIMENTS / f"{robot}_valid.yaml")
    if not quick and not all(p.is_file() for p in pair):
        raise DemoError(f"--robot {robot}: experiments/ has no {pair[0].name} / {pair[1].name} pair "
                        f"(use --quick, or write them with urident excite)")

    t0 = time.monotonic()

    def step(text: str) -> None:
        say(f"[{time.monotonic() - t0:6.1f} s] {text}")

    directory = new_run_directory(Path(root))
    step(f"writing everything to {directory}/")
    if quick:
        ident_traj, valid_traj = quick_trajectories(directory, robot=robot)
    else:
        ident_traj, valid_traj = pair
    start = load_trajectory(ident_traj).trajectory.q_start
    host = free_loopback_address()
    step(f"starting the simulated {spec.model or robot} controller on {host} (realistic unmodelled effects)")
    logs = {"ident": directory / "ident.csv", "valid": directory / "valid.csv"}
    config = directory / "session.yaml"
    # The validation trajectory may start far from where identification ended: a longer (still
    # collision-checked) approach at a moderate speed. Late control cycles, late samples and the
    # servo lag they add come from the host's load here (the controller is simulated on the same
    # cores), not from a robot at risk: the demo tolerates 0.5 s without a sample and 0.5 rad of
    # tracking error (the fastest joints of these runs lag about 0.2 rad on a busy host already).
    config.write_text("approach:\n  speed_rad_s: 0.6\n  acceleration_rad_s2: 1.0\n"
                      "  max_distance_rad: 3.2\nmonitors:\n  max_late_fraction: 0.5\n"
                      "  max_consecutive_late: 500\n  max_tracking_error_rad: 0.5\n"
                      f"  max_stale_periods: {round(0.5 * spec.controller_rate_hz)}\nrest_s: 0.5\n")
    with SimControllerProcess(host=host, robot=robot, effects=EFFECTS_PRESET, seed=seed,
                              initial_q=start + 0.05) as sim:
        for kind, trajectory in (("ident", ident_traj), ("valid", valid_traj)):
            step(f"run: {kind} trajectory {trajectory.name} at {spec.controller_rate_hz:g} Hz "
                 f"(live view -> {kind}_live.rrd)")
            ur.run_trajectory(trajectory, host, logs[kind], robot, config=config, assume_yes=True,
                              live=directory / f"{kind}_live.rrd")
        # the last run's check that its program stays stopped must end before the controller does
        from urident.session.handover import controller_turn

        with controller_turn(host, say):
            step("stopping the simulated controller")
    if sim.returncode not in (0, None):
        say(f"warning: the simulated controller exited with code {sim.returncode}")

    params = directory / "params.yaml"
    step("identify: OLS, bounded and physically consistent estimates")
    ident = ur.identify([logs["ident"]], spec, method="all")
    ident.save(params)
    (directory / "identification.txt").write_text(ident.report + "\n")
    say(ident.report)
    step("validate: e_N and per-joint RMS on the validation run")
    files = [params.with_suffix(".ols.yaml"), params.with_suffix(".bounded.yaml"), params]
    validation = ur.validate([str(p) for p in files], [logs["valid"]], spec)
    (directory / "validation.json").write_text(validation.to_json() + "\n")
    _plots(validation, directory / "plots")
    for name, r in zip(validation.params, validation.results):
        say(f"{name} ({r.method}): e_N = {r.e_n:.4f}, mean RMS {r.mean_rms_nm:.3f} N·m")
    step("gap: where the residual lies, which effect, how far it shrinks")
    gap = ur.diagnose_gap([logs["ident"]], [logs["valid"]], spec)
    (directory / "gap.json").write_text(gap.to_json())
    from urident.gap import format_report

    say(format_report(gap))
    _rerun_files(spec, gap, logs["valid"], params, directory)

    from urident.simcontroller.effects import parse_effects

    injected = tuple(e.as_dict() for e in parse_effects(EFFECTS_PRESET).entries)
    result = DemoResult(directory, validation.to_dict(), gap.to_dict(), time.monotonic() - t0,
                        spec.model or robot, injected)
    say("")
    say(summary(result))
    return result


def _plots(validation, directory: Path) -> None:
    """Measured against predicted torques of each parameters file, a PNG each."""
    from urident.viz.plots import plot_torques

    directory.mkdir(parents=True, exist_ok=True)
    for name, r in zip(validation.params, validation.results):
        plot_torques(r, directory / f"validation_{Path(name).stem}.png",
                     title=f"{Path(name).name} ({r.method}): e_N = {r.e_n:.4f}, mean RMS {r.mean_rms_nm:.2f} N·m")


def _rerun_files(spec, gap, valid_log: Path, params: Path, directory: Path) -> None:
    """gap.rrd (the diagnosis' residual maps) and validation.rrd (measured against predicted
    torques with the arm in 3-D)."""
    from urident.ident import load_prediction_params, predict_recordings
    from urident.logs import load_log
    from urident.viz.blueprint import torque_blueprint
    from urident.viz.gap_view import log_gap_result
    from urident.viz.recording import close_recording, open_recording
    from urident.viz.replay import log_prediction

    log_gap_result(open_recording("urident_gap", save=directory / "gap.rrd"), gap, spec)
    recording = load_log(valid_log, robot=spec.name)
    prediction = predict_recordings(load_prediction_params(params, spec), [recording], spec)
    rec = open_recording("urident_view", save=directory / "validation.rrd",
                         blueprint=torque_blueprint(joint_names=spec.joint_names))
    log_prediction(rec, spec, recording, prediction, f"{spec.name}: measured vs identified model")
    close_recording(rec)


def summary(result: DemoResult) -> str:
    lines = [f"urident demo finished in {result.seconds:.0f} s: {result.directory}/"]
    runs = result.validation.get("results", result.validation)
    runs = runs if isinstance(runs, list) else [runs]
    lines.append(f"validation on the second trajectory ({result.robot}, realistic unmodelled effects):")
    lines.append(f"  {'method':<11} {'e_N':>7}   RMS per joint [N·m]")
    for r in runs:
        rms = " ".join(f"{v:5.2f}" for v in r["rms_nm"])
        lines.append(f"  {r['method']:<11} {r['e_n']:7.4f}   {rms}")
    base, final = result.gap["baseline"], result.gap["final"]
    shrink = 100.0 * (base["e_n"] - final["e_n"]) / base["e_n"] if base["e_n"] else 0.0
    lines.append(f"gap diagnosis: e_N {base['e_n']:.4f} -> {final['e_n']:.4f} once the named "
                 f"effects are added ({shrink:.1f} % smaller)")
    findings = result.gap.get("findings", [])
    if not findings:
        lines.append("  no unmodelled effect found")
    for f in findings:
        alike = f.get("confounded_with") or []
        lines.append(f"  joint {f['joint']}: {f['effect']:<22} RMS {f['rms_before_nm']:.3f} -> "
                     f"{f['rms_after_nm']:.3f} N·m ({f['shrink_pct']:.1f} %), {f.get('regime', '')}"
                     + (f"; confounded with {', '.join(alike)}" if alike else ""))
    if result.injected:
        lines += injected_vs_found(result.injected, findings)
    lines.append("open the recordings with: rerun " + str(result.directory / "validation.rrd"))
    return "\n".join(lines)


def compare_effects(injected, findings) -> tuple[list[dict], list[dict]]:
    """Per injected effect (effects-file entries, joints 1-based): the joints a finding names it
    on, those where a finding is confounded with it (the diagnosis says the data cannot tell the
    two apart) and those it misses; and the findings no injected effect explains (invented). A
    finding names an effect on its ``joint``; an effect without joints (a payload) on any."""
    rows = []
    claimed = set()
    for e in injected:
        joints = list(e.get("joints") or [])
        named, confounded, missed = [], [], []
        for j in joints or [None]:
            hit = [k for k, f in enumerate(findings) if f["effect"] == e["name"] and (j is None or f["joint"] == j)]
            alike = [k for k, f in enumerate(findings) if not hit and any(
                a == e["name"] or (a.startswith(e["name"] + " on joint ") and (j is None or a.endswith(f" {j}")))
                for a in f.get("confounded_with") or [])]
            (named if hit else confounded if alike else missed).append(j)
            claimed.update(hit + alike)
        rows.append({"effect": e["name"], "joints": joints, "named": named, "confounded": confounded,
                     "missed": missed, "magnitude": {k: v for k, v in e.items() if k not in ("name", "joints")}})
    invented = [f for k, f in enumerate(findings) if k not in claimed]
    return rows, invented


def injected_vs_found(injected, findings) -> list[str]:
    """The summary's table: what the simulated controller injected beside what the diagnosis
    found (named, missed, invented, with magnitudes)."""
    rows, invented = compare_effects(injected, findings)
    by_key = {(f["effect"], f["joint"]): f for f in findings}
    n_named = sum(len(r["named"]) for r in rows)
    n_alike = sum(len(r["confounded"]) for r in rows)
    n_all = sum(len(r["named"]) + len(r["confounded"]) + len(r["missed"]) for r in rows)
    lines = [f"injected ({EFFECTS_PRESET} preset) vs diagnosed: {n_named} of {n_all} injected (effect, joint) "
             f"named, " + (f"{n_alike} confounded with a finding, " if n_alike else "") + f"{len(invented)} invented"]
    for r in rows:
        mag = ", ".join(f"{k} {_short(v)}" for k, v in r["magnitude"].items())
        where = "joints " + ",".join(map(str, r["joints"])) if r["joints"] else "arm"
        named = "; ".join(_found_text(by_key[(r["effect"], j)]) for j in r["named"]
                          if (r["effect"], j) in by_key)
        if not r["joints"] and r["named"]:
            named = "; ".join(_found_text(f) for f in findings if f["effect"] == r["effect"])
        missed = ",".join("arm" if j is None else str(j) for j in r["missed"])
        alike = ",".join("arm" if j is None else str(j) for j in r["confounded"])
        lines.append(f"  {r['effect']:<22} {where:<14} injected {mag}")
        lines.append(f"  {'':<22} {'':<14} named: {named or 'none'}; "
                     + (f"confounded with a finding: {alike}; " if alike else "") + f"missed: {missed or 'none'}")
    for f in invented:
        lines.append(f"  invented: {_found_text(f)}")
    return lines


def _found_text(f: dict) -> str:
    mag = ", ".join(f"{k} {_short(v)}" for k, v in (f.get("magnitude") or {}).items() if k != "coefficients")
    return (f"{f['effect']} on joint {f['joint']} ({f['shrink_pct']:.1f} % smaller RMS"
            + (f"; fitted {mag}" if mag else "") + ")")


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_short(x) for x in v) + "]"
    return str(v)
