"""Property test: malformed trajectory files always end in a one-line ConfigError naming the file,
never in another exception."""

import math
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_helpers import key_paths

from urident.errors import ConfigError
from urident.excitation import FourierTrajectory, Limits, load_trajectory, trajectory_document
from urident.excitation.fourier import base_frequency
from urident.model import load_robot


def _valid_document() -> dict:
    spec = load_robot("ur5")
    free = np.random.default_rng(0).normal(size=(6, 4)) * 0.05
    traj = FourierTrajectory.from_free(free, base_frequency(10.0), [0, -math.pi / 2, 0, 0, 0, 0], 10.0)
    return trajectory_document("ur5", traj, Limits.from_robot(spec), {"criterion": "cond", "seed": 1},
                               {"cond_theta": 100.0}, {"ok": True, "min_distance_m": 0.05})


VALID = _valid_document()
REQUIRED = [("format",), ("format_version",), ("robot",), ("trajectory",), ("limits",),
            *[("trajectory", k) for k in ("harmonics", "duration_s", "base_frequency_rad_s", "q0_rad",
                                          "a_rad_s", "b_rad_s")],
            *[("limits", k) for k in ("velocity_fraction", "acceleration_fraction", "torque_fraction",
                                      "position_margin_rad", "position_window_rad", "clearance_m",
                                      "floor_height_m")]]
# Values that are invalid wherever they are put.
JUNK = st.sampled_from([None, [], {}, float("nan"), float("inf"), [[1.0]], {"x": 1}, [None], "", 10 ** 400])




ALL_PATHS = [p for p in key_paths(VALID) if p and p[0] != "urident_version"] + [("urident_version",)]
# Leaves whose replacement by any junk value is invalid ('' is a valid robot? no: unknown robot).
REPLACEABLE = [p for p in ALL_PATHS if p[0] in ("format", "format_version", "robot", "trajectory", "limits",
                                                "urident_version", "optimization", "criteria", "check")]


def _copy(doc):
    return yaml.safe_load(yaml.safe_dump(doc))


def _set(doc, path, value):
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value


@st.composite
def malformed_documents(draw):
    doc = _copy(VALID)
    kind = draw(st.sampled_from(["replace", "delete", "unknown"]))
    if kind == "replace":
        path = draw(st.sampled_from(REPLACEABLE))
        value = draw(JUNK)
        if value == "" and path[0] in ("urident_version", "optimization", "criteria", "check"):
            value = None  # free-form strings are valid there
        if value == {} and path in (("optimization",), ("criteria",), ("check",)):
            value = []    # an empty optional section is valid
        _set(doc, path, value)
    elif kind == "delete":
        path = draw(st.sampled_from(REQUIRED))
        node = doc
        for key in path[:-1]:
            node = node[key]
        del node[path[-1]]
    else:
        section = draw(st.sampled_from([None, "trajectory", "limits", "optimization", "criteria", "check"]))
        key = draw(st.text(min_size=1, max_size=12).filter(lambda k: k not in VALID and k not in
                                                            VALID.get(section or "", {})))
        (doc if section is None else doc[section])[key] = draw(st.integers())
    # Sometimes also break something else.
    if draw(st.booleans()):  # (never in an optional section: it could undo the first mutation)
        extra_path = draw(st.sampled_from([p for p in REPLACEABLE if p[0] in ("trajectory", "limits")]))
        try:
            _set(doc, extra_path, draw(JUNK))
        except (KeyError, IndexError, TypeError):
            pass
    return doc


def _dump(doc) -> str:
    try:
        return yaml.safe_dump(doc)
    except (OverflowError, ValueError):
        return yaml.dump(doc)


FUZZ = settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=malformed_documents())
def test_malformed_documents_raise_config_error(tmp_path, doc):
    path = tmp_path / "fuzz.yaml"
    path.write_text(_dump(doc))
    _expect_config_error(path)


@FUZZ
@given(text=st.text(max_size=300))
def test_arbitrary_text_raises_config_error(tmp_path, text):
    path = tmp_path / "fuzz.yaml"
    path.write_text(text, encoding="utf-8")
    _expect_config_error(path)


@FUZZ
@given(data=st.binary(max_size=200))
def test_arbitrary_bytes_raise_config_error(tmp_path, data):
    path = tmp_path / "fuzz.yaml"
    path.write_bytes(data)
    _expect_config_error(path)


@FUZZ
@given(lines=st.lists(st.integers(0, 400), min_size=1, max_size=3), cut=st.booleans())
def test_truncated_or_line_dropped_files_raise_config_error(tmp_path, lines, cut):
    text = _dump(VALID)
    if cut:  # anywhere before the required 'limits' section
        text = text[: lines[0] % text.index("\nlimits:")]
    else:
        kept = text.splitlines()
        drop = {i % len(kept) for i in lines}
        # Dropping only optional lines may leave a valid file; force a required one out as well.
        drop.add(kept.index(next(line for line in kept if line.startswith("  duration_s"))))
        text = "\n".join(line for i, line in enumerate(kept) if i not in drop)
    path = tmp_path / "fuzz.yaml"
    path.write_text(text)
    _expect_config_error(path)


def _expect_config_error(path: Path) -> None:
    try:
        load_trajectory(path)
    except ConfigError as exc:
        message = str(exc)
        assert str(path) in message and "\n" not in message
    else:
        raise AssertionError(f"loaded a malformed file:\n{path.read_text()[:500]}")
