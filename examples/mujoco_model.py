"""Diagnose a MuJoCo model against a robot's log: what the simulator gets wrong, which of it MJCF
can express, and the corrected model measured by MuJoCo itself.

Any MJCF or URDF of the arm works (MuJoCo Menagerie's, UR's ROS description, your own); here the
robot file's nominal UR5, exported by urident and given Menagerie's drive values (armature 0.1, no
damping, no friction), stands in for a downloaded one. Needs the `mujoco` extra. Run from the
repository root:  python examples/mujoco_model.py [MODEL.xml]
"""

import sys
import tempfile
from pathlib import Path

import mujoco

import urident as ur

valid = ["logs/sample_valid.csv"]   # a UR5 run the model should reproduce
with tempfile.TemporaryDirectory() as out:
    model = sys.argv[1] if len(sys.argv) > 1 else str(Path(out) / "ur5_nominal.xml")
    if len(sys.argv) == 1:
        ur.export_model(None, model, robot="ur5")          # MJCF built through mujoco.MjSpec
        spec = mujoco.MjSpec.from_file(model)              # a downloaded model's drive values
        for joint in spec.joints:
            joint.armature, joint.damping, joint.frictionloss = 0.1, 0.0, 0.0
        Path(model).write_text(spec.to_xml())
    sim = ur.diagnose_sim(model, valid, "ur5", write_sim=Path(out) / "ur5_corrected.xml")

    for f in sim.findings:
        where = "MJCF can express it" if f.expressible else "MJCF cannot express it"
        print(f"joint {f.joint}: {f.effect:<24} {f.shrink_pct:5.1f} % smaller RMS; {where}")
    shrink = " ".join(f"{v:5.1f}" for v in sim.predicted_shrink_pct)
    print(f"predicted shrink per joint [%]: {shrink}")
    if sim.corrected is not None:   # the corrected model, run through MuJoCo's inverse dynamics
        measured = " ".join(f"{v:5.1f}" for v in sim.corrected.shrink_pct)
        print(f"corrected model, measured by MuJoCo [%]: {measured}")
