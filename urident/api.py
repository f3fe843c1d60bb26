"""urident's Python API: the analysis steps of the command line as functions, for notebooks and
scripts. One import::

    import urident as ur

    ident = ur.identify(["ident.csv"], robot="ur10e", method="all", preset="auto")
    ident.save("params.yaml")
    check = ur.validate(ident, ["valid.csv"])
    print(check.e_n, check.rms_nm)              # the paper's e_N; per-joint RMS [N·m], (6,)
    gap = ur.diagnose_gap(["ident.csv"], ["valid.csv"], robot="ur10e")

Logs are given as paths or as :class:`urident.logs.Recording` objects (``ur.load_log`` reads one
with every option of the command line's log flags). Every result is a frozen dataclass with arrays
in SI units, ``to_dict()`` and ``to_json()``; the commands' ``--json-out`` writes exactly that
document. Errors a user can cause raise :class:`urident.errors.UridentError` subclasses (one-line
message naming the file, key or argument; ``exit_code`` is what the command line returns).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np

from urident.errors import ConfigError
from urident.logs import Recording, load_log

METHODS = ("ols", "bounded", "consistent")
__all__ = ["Identification", "Validation", "calibrate_drive_gains", "check_trajectory",
           "design_excitation", "diagnose_gap", "diagnose_sim", "export_model", "identify",
           "identify_payload", "load_log", "run_trajectory", "validate"]


def _spec(robot):
    from urident.model import RobotSpec, load_robot

    return robot if isinstance(robot, RobotSpec) else load_robot(robot)


def _recordings(logs, robot: str, **log_options) -> Iterator[Recording]:
    """Each log as a :class:`Recording`, loaded one at a time (a path, a Recording, or an
    iterable of them)."""
    if isinstance(logs, (str, Path, Recording)):
        logs = [logs]
    for log in logs:
        yield log if isinstance(log, Recording) else load_log(log, robot=robot, **log_options)


def _json(document: dict, indent: int | None) -> str:
    return json.dumps(document, indent=indent)


def sibling(path: Path, method: str) -> Path:
    """Where the estimate of ``method`` goes beside the primary parameters file ``path``."""
    return path.with_name(f"{path.stem}.{method}{path.suffix or '.yaml'}")


# --------------------------------------------------------------------------- identify
@dataclass(frozen=True)
class Identification:
    """Identified parameters, one :class:`urident.ident.IdentifiedModel` per method.

    ``method`` is the primary one (the physically consistent estimate when several were asked);
    ``report`` is the comparison table the command prints (the torque signal of each log, the
    estimates, the logs used); ``selection`` says what a preset chose by cross-validation;
    ``data`` is the prepared identification data (:class:`urident.ident.Prepared`: t, q, qd, qdd,
    measured tau) the estimates were fitted on."""

    robot: str
    method: str
    models: Mapping[str, object]
    report: str
    selection: str = ""
    data: object = field(default=None, repr=False, compare=False)  # the prepared data fitted on

    @property
    def model(self):
        """The primary method's :class:`urident.ident.IdentifiedModel`."""
        return self.models[self.method]

    def parameters(self, method: str | None = None) -> dict[str, float]:
        """Base parameter name → value (SI units) of ``method`` (default: the primary one)."""
        m = self.models[method or self.method]
        return {name: float(v) for name, v in zip(m.names, m.values)}

    def save(self, path: str | Path, overwrite: bool = False) -> list[Path]:
        """Write the primary estimate to ``path`` and every other method's beside it
        (``PARAMS.ols.yaml``, ...); returns the files written."""
        from urident.ident import save_params

        path = Path(path)
        written = []
        for method in (self.method, *(m for m in self.models if m != self.method)):
            target = path if method == self.method else sibling(path, method)
            save_params(self.models[method], target, overwrite=overwrite)
            written.append(target)
        return written

    def to_dict(self) -> dict:
        methods = {}
        for name, m in self.models.items():
            methods[name] = {"parameters": self.parameters(name),
                             "sigma": [float(v) for v in m.sigma],
                             "n_samples": int(m.n_samples),
                             "train_e_n": None if not np.isfinite(m.train_e_n) else float(m.train_e_n),
                             "train_rms_nm": None if m.train_rms is None else [float(v) for v in m.train_rms],
                             "drive_gains": [float(v) for v in m.drive_gains]}
        return {"robot": self.robot, "method": self.method, "methods": methods,
                "selection": self.selection, "report": self.report}

    def to_json(self, indent: int | None = 2) -> str:
        return _json(self.to_dict(), indent)


def identify(logs, robot, method: str = "ols", preset: str | None = None, *, model=None,
             weighting: str | None = None, select_dahl_rad: bool | None = None, preprocess=None,
             drive_gains=None, payload=None, regularisation: float | None = None,
             log_options: Mapping | None = None, progress: bool = False,
             sessions: bool = False, overrides: Mapping | None = None,
             option_names: Mapping | None = None, select_filter_hz: bool | None = None) -> Identification:
    """Identify base parameters from ``logs`` (paths or Recordings, loaded one at a time).

    ``method``: ``ols`` (the paper's), ``bounded``, ``consistent`` or ``all``. ``preset``: a named
    configuration (``paper``, ``auto``, also spelled ``real-robot`` or ``best``, or the fixed
    ``ur10e-2020``: :data:`urident.ident.presets.PRESETS`); ``model`` (a
    :class:`urident.ident.ModelConfig`), ``weighting``, ``select_dahl_rad`` and ``overrides``
    (single model options, :func:`urident.ident.presets.resolve_model`; ``option_names``: how
    the caller spells them in errors) override it. ``preprocess``: a
    :class:`urident.ident.PreprocessConfig` (default: rest trimmed). ``drive_gains``: six joint-side
    gains i_G·k [N·m/A], a GAINS.yaml path, or None for the robot file's. ``payload``: a
    :class:`urident.model.payload.Payload` or a payload file the logs carry (its torque is removed).
    ``log_options``: keyword arguments of :func:`urident.logs.load_log` for paths. ``sessions``:
    each log is a session of its own; a per-session torque offset and friction scale are kept per
    joint where blocked CV says they pay (:func:`urident.ident.sessions.fit_sessions`).
    ``select_filter_hz``: whether ``auto`` chooses the acceleration filter's corner by blocked CV
    (:func:`urident.ident.presets.choose_on_data`); default yes unless ``preprocess`` sets a corner
    other than the default."""
    from urident.ident import PreprocessConfig, identify_all, prepare
    from urident.ident.estimate_consistent import DEFAULT_REGULARISATION
    from urident.ident.presets import choose_on_data, resolve_model
    from urident.ident.report import comparison_report, logs_used
    from urident.ident.torque import describe_signal, resolve_drive_gains

    if method not in (*METHODS, "all"):
        raise ConfigError(f"method {method!r} unknown (known: {', '.join(METHODS)}, all)")
    methods = METHODS if method == "all" else (method,)
    spec = _spec(robot)
    given = {k: v for k, v in (("weighting", weighting), ("select_dahl_rad", select_dahl_rad)) if v is not None}
    choice = resolve_model(preset, {**dict(overrides or {}), **given}, model=model, names=option_names)
    config = preprocess if preprocess is not None else PreprocessConfig(trim_rest=True)
    gains = resolve_drive_gains(spec, drive_gains)
    signals: list[str] = []  # which signal gave each log's torques, said before it is freed

    def loaded() -> Iterator[Recording]:
        paths = logs
        if progress:
            from urident.progress import progress_iter

            paths = progress_iter([logs] if isinstance(logs, (str, Path, Recording)) else list(logs),
                                  "loading logs")
        for recording in _recordings(paths, spec.name, **dict(log_options or {})):
            signals.append(describe_signal(recording))
            yield recording

    data = prepare(loaded(), spec, config, gains)
    measured = data
    if payload is not None:
        from urident.ident.payload import without_payload

        tool = _payload(payload, spec)
        data = without_payload(spec, tool, data)
    if select_filter_hz is None:
        select_filter_hz = config.filter_hz == PreprocessConfig().filter_hz
    resolved = choose_on_data(spec, data, choice, config=config, select_corner=select_filter_hz)
    model, weighting, selection = resolved.model, resolved.weighting, resolved.text()
    if resolved.data is not None:   # auto paired the torque with later motion or chose another corner: fit and record it so
        data = resolved.data if payload is None else without_payload(spec, tool, resolved.apply(measured, config.prewarp))
        config = resolved.preprocess_config(config)
    if sessions:
        from urident.ident.sessions import fit_sessions

        data, session_terms = fit_sessions(spec, data, model, weighting)
        selection = (selection + "\n" if selection else "") + session_terms.text()
    reg = DEFAULT_REGULARISATION if regularisation is None else regularisation
    models = identify_all(spec, data, methods, model, weighting, reg, config)
    report = "\n".join(signals) + "\n" + comparison_report(models)
    if choice.preset:
        asked = "" if preset == choice.preset else f" (asked for as {preset})"   # an alias: real-robot, best
        report = f"preset {choice.preset}{asked}\n" + report
    if selection:
        report = selection + "\n" + report
    report = report + "\n" + logs_used(data.provenance)
    priors = ("inertia_com", "rotor_inertia", "viscous_friction", "coulomb_friction")
    note = spec.nominal_note(priors + (("torque_constant", "gear_ratio") if drive_gains is None else ()))
    if note:  # torques from currents use the file's torque constants; priors and bounds its values
        report = report + "\n" + note
    primary = "consistent" if method == "all" else method
    return Identification(spec.name, primary, dict(models), report, selection, data)


def _payload(payload, spec):
    from urident.ident.payload_file import load_payload

    return load_payload(payload, spec) if isinstance(payload, (str, Path)) else payload


# --------------------------------------------------------------------------- validate
@dataclass(frozen=True)
class Validation:
    """Predicted against measured torques of the validation logs, one
    :class:`urident.ident.ValidationResult` per parameters file (``params`` names each).

    The first result's metrics are the validation's: ``e_n`` (the paper's normalised error),
    ``rms_nm`` (6,) N·m, ``rre_pct`` (6,) %, and its arrays ``t`` (N,) s, ``tau_measured`` and
    ``tau_predicted`` (N, 6) N·m."""

    results: tuple
    params: tuple[str, ...]
    payload: str | None = None
    shifts: tuple = ()   # per result, the session shift fitted on its residual (or None)

    @property
    def result(self):
        return self.results[0]

    @property
    def e_n(self) -> float:
        return float(self.result.e_n)

    @property
    def rms_nm(self) -> np.ndarray:
        return self.result.rms_nm

    @property
    def rre_pct(self) -> np.ndarray:
        return self.result.rre_pct

    @property
    def t(self) -> np.ndarray:
        return self.result.t

    @property
    def tau_measured(self) -> np.ndarray:
        return self.result.tau_measured

    @property
    def tau_predicted(self) -> np.ndarray:
        return self.result.tau_predicted

    def to_dict(self) -> dict:
        """The document ``urident validate --json-out`` writes: the first result's metrics, and
        every result under ``results`` when several parameters files were compared."""
        shifts = self.shifts or (None,) * len(self.results)

        def entry(p, r, shift):
            d = dict(r.as_dict(), params=p)
            if shift is not None:
                d["session_shift"] = shift.as_dict()
            return d

        document = dict(entry(self.params[0], self.result, shifts[0]), payload=self.payload)
        if len(self.results) > 1:
            document["results"] = [entry(*e) for e in zip(self.params, self.results, shifts)]
        return document

    def to_json(self, indent: int | None = 2) -> str:
        return _json(self.to_dict(), indent)


def validate(params, logs, robot=None, *, payload=None, drive_gains=None,
             log_options: Mapping | None = None, progress: bool = False,
             names: Sequence[str] | None = None, payload_name: str | None = None,
             session_shift: bool = False, **preprocess_overrides) -> Validation:
    """Predict the torques of ``logs`` with ``params`` and compare with the measured ones.

    ``params``: an :class:`Identification` (its primary estimate), an IdentifiedModel, a
    parameters file, or a list of them to compare. Preprocessing follows each parameters file
    (:func:`urident.ident.prediction_config`); ``preprocess_overrides`` (``filter_hz``,
    ``trim_rest``, ...) override it. ``robot`` defaults to the parameters' robot; ``names``
    label the parameters in the result (default: their files), ``payload_name`` the payload.
    ``session_shift``: also fit a per-joint torque offset and friction scale on each residual and
    say how much of the error such a session shift explains."""
    from urident.ident import load_params, predict_recordings, prediction_config
    from urident.ident.identify import check_compatible

    items = list(params) if isinstance(params, (list, tuple)) else [params]
    if not items:
        raise ConfigError("validate needs at least one parameters file")
    models = []
    for item in items:
        if isinstance(item, Identification):
            models.append((f"<identified {item.method}>", item.model))
        elif isinstance(item, (str, Path)):
            models.append((str(item), load_params(item)))
        else:
            models.append((f"<{getattr(item, 'method', 'parameters')}>", item))
    if names is not None:
        models = [(str(label), m) for label, (_, m) in zip(names, models)]
    spec = _spec(robot or models[0][1].robot)
    for name, m in models:
        if m.robot != spec.name:
            raise ConfigError(f"{name}: parameters are for robot {m.robot!r}, validating on {spec.name!r}")
    load = _payload(payload, spec) if payload is not None else None
    paths = logs
    if progress and not isinstance(logs, (str, Path, Recording)):
        from urident.progress import progress_iter

        paths = progress_iter(list(logs), "loading logs")
    recordings = _recordings(paths, spec.name, **dict(log_options or {}))
    if len(models) > 1:  # each parameters file predicts the same recordings; one file streams them
        recordings = list(recordings)
    results, shifts = [], []
    for name, m in models:
        check_compatible(m, spec, name)
        config = prediction_config(m, **preprocess_overrides)
        prediction = predict_recordings(m, recordings, spec, config=config, payload=load,
                                        drive_gains=drive_gains)
        results.append(prediction.validation())
        shift = None
        if session_shift:
            from urident.ident.sessions import session_shift as fit_shift

            shift = fit_shift(m, spec, prediction.data, prediction.tau_predicted)
        shifts.append(shift)
    if payload_name is None and isinstance(payload, (str, Path)):
        payload_name = str(payload)
    return Validation(tuple(results), tuple(n for n, _ in models), payload_name, tuple(shifts))


# --------------------------------------------------------------------------- payloads, drive gains
def _named(logs, robot: str, options: Mapping | None) -> list[tuple[str, Recording]]:
    """(name, Recording) per log, loaded in order: a path's name is the path, a Recording's its
    source file."""
    items = [logs] if isinstance(logs, (str, Path, Recording)) else list(logs)
    recordings = _recordings(items, robot, **dict(options or {}))
    return [(str(log.source or f"<recording {k + 1}>") if isinstance(log, Recording) else str(log), rec)
            for k, (log, rec) in enumerate(zip(items, recordings))]


def identify_payload(logs, params, robot=None, *, unloaded=None, mass_range=None, drive_gains=None,
                     log_options: Mapping | None = None, params_label: str | None = None,
                     unloaded_labels: Sequence[str] | None = None,
                     unloaded_wrist_labels: Sequence[str] | None = None):
    """A tool's mass, centre of mass and inertia (UR's flange frame) from ``logs`` recorded with it
    mounted, the arm's identified ``params`` (an :class:`Identification`, IdentifiedModel or
    parameters file) fixed. ``unloaded``: runs of the same motion without the tool (a tare,
    needed for the inertia; each must be a loaded log's motion). ``mass_range``: (low, high) kg.
    Returns a :class:`urident.ident.payload_fit.PayloadIdentification` (``payload`` is the
    :class:`urident.model.payload.Payload`; ``save()`` writes the payload file)."""
    from urident.ident import load_params
    from urident.ident.payload_fit import fit_payload

    if isinstance(params, Identification):
        label, arm = f"<identified {params.method}>", params.model
    elif isinstance(params, (str, Path)):
        label, arm = str(params), load_params(params)
    else:
        label, arm = f"<{getattr(params, 'method', 'parameters')}>", params
    spec = _spec(robot or arm.robot)
    loaded = _named(logs, spec.name, log_options)
    tare = _named(unloaded, spec.name, log_options) if unloaded else []
    return fit_payload(arm, spec, loaded, tare, mass_range=mass_range, drive_gains=drive_gains,
                       params_label=params_label or label, tare_labels=unloaded_labels,
                       tare_wrist_labels=unloaded_wrist_labels)


def calibrate_drive_gains(without, with_, robot, payload, *, reduced: bool = False,
                          log_options: Mapping | None = None):
    """The six joint drive gains i_G·k [N·m/A] from runs ``without`` and ``with_`` a load of known
    mass and centre of mass (``payload``: a :class:`urident.model.payload.Payload` or payload
    file; a point mass unless it carries an inertia). The logs' motor currents are used whatever
    torques they also carry. Returns a :class:`urident.ident.gains_fit.DriveGainCalibration`
    (``save()`` writes the GAINS.yaml every ``drive_gains=`` and ``--drive-gains`` accept)."""
    from urident.ident.gains_fit import calibrate_gains

    from urident.logs.recording import with_signal

    spec = _spec(robot)
    runs = [[(name, with_signal(rec, "current", name)) for name, rec in _named(logs, spec.name, log_options)]
            for logs in (without, with_)]
    return calibrate_gains(spec, runs[0], runs[1], _payload(payload, spec), reduced=reduced)


# --------------------------------------------------------------------------- running a trajectory
def run_trajectory(trajectory, host: str, out, robot=None, *, config=None, repeat: int = 1,
                   check_only: bool = False, assume_yes: bool = False, confirm=None, payload=None,
                   record_periods: bool = False, live=None, say=None):
    """Run a trajectory file on the controller at ``host`` over RTDE (ur_rtde's servoJ at the
    controller's rate) and record it to ``out`` (a CSV with its ``.yaml`` sidecar).

    Nothing moves unless the whole trajectory passes its checks at that rate (joint, velocity,
    acceleration, torque and collision limits, with ``payload`` or the file's); the session ends
    with servoStop and stopScript whatever happens, and an abort keeps every sample recorded.
    ``config``: an experiment configuration file or :class:`urident.session.ExperimentConfig`
    (approach, monitors, rest); ``check_only``: run the checks, connect, move nothing.
    ``assume_yes`` starts without asking; otherwise ``confirm(question) -> bool`` is asked (none:
    refused). ``live``: a :class:`urident.viz.LiveStreamer` fed by the control loop, or a path to
    save the live view to (``.rrd``). Returns a :class:`urident.session.RunResult` (``to_dict()``,
    ``to_json()``); raises
    :class:`urident.errors.SafetyError` before any motion, :class:`urident.errors.SessionAborted` after it
    started."""
    from urident.session import ExperimentConfig, RunRequest, load_experiment_config, run_session

    spec, robot_ref = _run_robot(robot, trajectory)
    if not isinstance(config, ExperimentConfig):
        config = load_experiment_config(config)
    if isinstance(live, (str, Path)):
        from urident.viz import LiveStreamer

        live = LiveStreamer(spec, None, save=live)
    request = RunRequest(robot=robot_ref, host=host, trajectory=Path(trajectory), out=Path(out), config=config,
                         repeat=repeat, check_only=check_only, assume_yes=assume_yes,
                         record_periods=record_periods,
                         payload=_payload(payload, spec) if payload is not None else None)
    return run_session(request, say=say, confirm=confirm, live=live)


def _run_robot(robot, trajectory):
    """(RobotSpec, what the session loads it from): a name or robot file as given (a file outside
    urident's robots loads again in the session process), else the trajectory file's robot."""
    from urident.model import RobotSpec

    if robot is None:
        from urident.excitation import load_trajectory

        spec = load_trajectory(trajectory).spec
        return spec, str(spec.source)
    if isinstance(robot, RobotSpec):
        return robot, str(robot.source)
    return _spec(robot), str(robot)


# --------------------------------------------------------------------------- gap, trajectories
def diagnose_gap(ident_logs, valid_logs, robot, *, params=None, drive_gains=None, payload=None,
                 log_options: Mapping | None = None, check_logs=None, **config):
    """Where the baseline model's residual on ``valid_logs`` lies, which unmodelled effect explains
    it and how far it shrinks once added. The baseline is identified on ``ident_logs`` (the
    paper's model), or is ``params`` (an :class:`Identification`, IdentifiedModel or parameters
    file); ``payload``: a known tool on the flange; ``config`` sets
    :class:`urident.gap.GapConfig` fields. ``check_logs``: held-out logs the findings are scored on
    (``result.check``). Returns a :class:`urident.gap.GapResult` (``to_dict()``/``to_json()`` give
    the document ``urident gap --json-out`` writes)."""
    from urident.gap import GapConfig, diagnose
    from urident.ident import load_params

    spec = _spec(robot)
    if isinstance(params, Identification):
        params = params.model
    elif isinstance(params, (str, Path)):
        params = load_params(params)
    options = dict(log_options or {})
    ident = list(_recordings(ident_logs, spec.name, **options))
    valid = list(_recordings(valid_logs, spec.name, **options))
    result = diagnose(ident, valid, spec, params=params, drive_gains=drive_gains,
                      config=replace(GapConfig(), **config), payload=_payload(payload, spec)
                      if payload is not None else None)
    if check_logs is not None:
        from urident.gap.check import check_findings

        result = replace(result, check=check_findings(result, list(_recordings(check_logs, spec.name, **options)),
                                                      spec, drive_gains=drive_gains, params=params))
    return result


def check_trajectory(trajectory, robot=None, rate_hz: float | None = None, payload=None):
    """Every constraint of a trajectory file (or a loaded :class:`urident.excitation.TrajectoryFile`)
    checked densely at ``rate_hz`` (default: the robot's controller rate), with the file's limits,
    for the file's robot (``robot``, if given, must be it),
    with and without ``payload`` (default: the one the file records). Returns a
    :class:`urident.excitation.CheckReport` (``ok``, ``violations``)."""
    from urident.excitation import TrajectoryFile, load_trajectory
    from urident.excitation import check_trajectory as check

    loaded = trajectory if isinstance(trajectory, TrajectoryFile) else load_trajectory(trajectory)
    spec = loaded.spec
    if robot is not None and _spec(robot).name != spec.name:
        raise ConfigError(f"{loaded.path}: a trajectory for robot {spec.name!r}, not {_spec(robot).name!r}")
    rate = rate_hz or spec.controller_rate_hz
    load = _payload(payload, spec) if payload is not None else loaded.payload
    return check(spec, loaded.trajectory, rate, loaded.limits, payload=load)


# --------------------------------------------------------------------------- simulator models
def diagnose_sim(model, valid_logs, robot, *, model_label: str | None = None, joint_map: Mapping | None = None,
                 drive_gains=None, write_sim: str | Path | None = None, overwrite: bool = False,
                 valid_labels: Sequence[str] | None = None, log_options: Mapping | None = None, **config):
    """The sim-to-real gap of a simulator model as it is (``urident gap --sim``): ``model`` an MJCF
    or URDF path (or a loaded :class:`urident.sim.models.SimModel`) of ``robot``, through its own
    inverse dynamics on ``valid_logs``; which findings its format can express, the drive terms not
    found and below what, the predicted shrink and, with ``write_sim`` (a path of the same format),
    the model written with the expressible findings and measured by its simulator. ``joint_map``:
    robot joint → the model's joint name; ``config`` sets :class:`urident.gap.GapConfig` fields
    (``max_effects`` defaults to 30). Returns a :class:`urident.gap.sim_report.SimGapReport`
    (``lines()`` the command's report, ``to_json()`` its ``--json-out``)."""
    from urident.gap import GapConfig
    from urident.gap.sim_report import SIM_MAX_EFFECTS, diagnose_sim_model
    from urident.sim.models import SimModel, load_sim_model

    spec = _spec(robot)
    joint_map = dict(joint_map) if joint_map else None
    sim = model if isinstance(model, SimModel) else load_sim_model(model, spec, joint_map=joint_map)
    named = _named(valid_logs, spec.name, log_options)
    valid = [rec for _, rec in named]
    valid_labels = list(valid_labels) if valid_labels is not None else [name for name, _ in named]
    return diagnose_sim_model(sim, valid, spec, model_label=model_label if model_label is not None else
                              (str(model) if not isinstance(model, SimModel) else None),
                              drive_gains=drive_gains, config=replace(GapConfig(max_effects=SIM_MAX_EFFECTS), **config),
                              write_to=write_sim, overwrite=overwrite, valid_labels=valid_labels,
                              joint_map=joint_map)


def export_model(params, out: str | Path, *, format: str | None = None, robot=None, name: str | None = None,
                 payload=None, valid_logs=None, log_options: Mapping | None = None, overwrite: bool = False,
                 label: str | None = None, payload_label: str | None = None,
                 valid_labels: Sequence[str] | None = None):
    """Write a simulator model of the arm (``urident export``): ``params`` (an
    :class:`Identification`, IdentifiedModel or parameters file) with its physically consistent
    estimate, or None for ``robot``'s nominal values. ``format``: ``mjcf`` (built through
    ``mujoco.MjSpec``) or ``urdf``, by ``out``'s suffix when None. ``payload``: a Payload or payload
    file, a body on the flange; ``valid_logs``: each identified term the format cannot express gets
    its share of their torque. Returns a :class:`urident.sim.export.ExportedModel` (``lines()`` what
    the command prints; ``to_dict()``/``to_json()``)."""
    from urident.ident import load_params
    from urident.sim.export import export_identified, export_nominal
    from urident.sim.models import model_format

    fmt = format or model_format(out)
    if params is None:
        if robot is None:
            raise ConfigError("export: the robot file's nominal values need a robot")
        if valid_logs:
            raise ConfigError("--valid: shares are of identified terms; --nominal has none")
        spec = _spec(robot)
        load = _payload(payload, spec) if payload is not None else None
        return export_nominal(spec, out, fmt, name=name, payload=load,
                              payload_label=payload_label or (str(payload) if payload is not None else None),
                              overwrite=overwrite)
    if isinstance(params, Identification):
        label, params = label or f"<identified {params.method}>", params.model
    elif isinstance(params, (str, Path)):
        label, params = label or str(params), load_params(params)
    else:
        label = label or f"<{getattr(params, 'method', 'parameters')}>"
    spec = _spec(robot or params.robot)
    load = _payload(payload, spec) if payload is not None else None
    named = [] if valid_logs is None else _named(valid_logs, spec.name, log_options)
    recordings = [rec for _, rec in named]
    valid_labels = list(valid_labels) if valid_labels is not None else [name for name, _ in named]
    return export_identified(params, spec, out, fmt, label=label, name=name, payload=load,
                             payload_label=payload_label or (str(payload) if payload is not None else None),
                             valid_recordings=recordings, valid_labels=valid_labels, overwrite=overwrite)


# --------------------------------------------------------------------------- excitation design
from typing import TYPE_CHECKING  # noqa: E402

if TYPE_CHECKING:  # loaded on the call: the optimiser brings scipy.optimize and the worker pool
    from urident.excitation.design import ExcitationDesign


def design_excitation(robot, *, harmonics: int = 5, duration_s: float | None = None, seed: int = 0,
                      reduced: bool = False, budget_s: float | None = None, for_payload: bool = False,
                      payload=None, tool=None, progress: bool = False, **options) -> ExcitationDesign:
    """Optimise an excitation trajectory (the paper's eq. 25-26, what ``urident excite`` does): a
    Fourier series of order ``harmonics`` over ``duration_s`` seconds (default 20; 30 with
    ``for_payload``), at rest at both ends, minimising cond(Λ) of the base regressor (``reduced``:
    the paper's 33 base parameters instead of 52) within the joint, velocity, acceleration, torque
    and collision limits, then checked densely at the controller rate. ``seed`` makes it
    reproducible; ``budget_s`` caps the search's wall time (the result says how far from converged
    it stopped).

    ``robot``: a name, a robot file or a :class:`urident.model.RobotSpec`. ``payload``: a load the
    torque checks include (a payload file or :class:`urident.ident.payload.Payload`; a file's capsule
    is the tool's size); ``tool``: the tool's :class:`urident.model.robot.ToolCapsule` for the
    collision checks; ``for_payload``: design for the payload's ten parameters instead (needs the
    tool's size). ``options``: ``periods``, ``criterion`` (``cond`` or ``logdet``), ``q0``,
    ``starts``, ``iterations``, ``margins`` (a mapping of :class:`urident.excitation.Margins`
    fields), ``max_velocity_rad_s`` (every joint's |q̇| bound besides the margins'), ``library`` (the arm's shipped
    designs join the random starts: True, False, or None, the default: with seed 0 only) as in :func:`urident.excitation.design.design`. The starts run in spawned processes:
    a script calling this needs the ``if __name__ == "__main__":`` guard.

    Returns an :class:`urident.excitation.design.ExcitationDesign`: ``trajectory``, ``cond``
    (cond(Θ̄_B) at the controller rate), ``convergence``, ``check`` (the dense check's report),
    ``save(path)`` (the trajectory file ``urident run`` and ``check-trajectory`` read; its text is
    read back and checked before it is written), ``to_dict()``/``to_json()`` (that file's document)."""
    from urident.excitation.design import design

    load, source = None, "payload"
    if payload is not None:
        load = _payload(payload, _spec(robot))
        source = f"payload {payload}" if isinstance(payload, (str, Path)) else "payload"

    def say(message: str) -> None:
        import sys

        print(f"design_excitation: {message}", file=sys.stderr, flush=True)

    return design(robot, harmonics=harmonics, duration_s=duration_s, seed=seed, reduced=reduced,
                  budget_s=budget_s, for_payload=for_payload, payload=load, tool=tool, payload_source=source,
                  progress=say if progress else None, **options)


