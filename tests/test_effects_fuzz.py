"""Hypothesis: any effects file either loads or fails with a one-line ConfigError naming it."""

from __future__ import annotations

import math

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urident.errors import ConfigError
from urident.model import load_robot
from urident.simcontroller.effects import EFFECT_NAMES, catalogue, load_effects, parse_effects_text

LABEL = "fuzz.yaml"
PARAM_KEYS = sorted({p.key for e in catalogue() for p in e.params})
SPEC = load_robot("ur5")

scalars = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(-10, 10),
    st.booleans(),
    st.none(),
    st.sampled_from(["", "abc", "torque", "friction", "1.5"]),
)
values = st.one_of(scalars, st.lists(scalars, max_size=7))
joints = st.one_of(st.lists(st.integers(-1, 8), max_size=7), scalars)
entries = st.dictionaries(
    st.one_of(st.sampled_from(["name", "joints", *PARAM_KEYS]), st.text(max_size=8)),
    st.one_of(values, joints, st.sampled_from(EFFECT_NAMES)),
    max_size=5,
)
documents = st.one_of(
    st.fixed_dictionaries({"effects": st.lists(
        st.one_of(entries, st.fixed_dictionaries({"name": st.sampled_from(EFFECT_NAMES)},
                                                 optional={k: values for k in PARAM_KEYS[:6]}),
                  scalars), max_size=4)}),
    st.dictionaries(st.text(max_size=10), values, max_size=3),
    values,
)


def _check(text: str) -> None:
    try:
        config = parse_effects_text(text, LABEL)
    except ConfigError as exc:
        message = str(exc)
        assert "\n" not in message
        assert message.startswith(LABEL)
        return
    es = load_effects(config, spec=SPEC)
    for entry in config.entries:
        for value in entry.values.values():
            if isinstance(value, np.ndarray):
                # a per-joint parameter is set on its joints only; a vector (a payload's com) whole
                checked = value[list(entry.joints)] if value.shape == (6,) else value
                assert np.all(np.isfinite(checked))
            elif isinstance(value, float):
                assert math.isfinite(value)
    z = np.zeros(6)
    assert np.all(np.isfinite(es.extra_torque(0.0, z, z + 0.1, z, z + 1.0, z + 30.0)))
    assert np.all(np.isfinite(es.measure_current(0.0, z + 0.5, z, z, z + 30.0)))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents)
def test_structured_effects_documents(doc):
    _check(yaml.safe_dump(doc))


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_arbitrary_text(text):
    _check(text)
