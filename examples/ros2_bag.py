"""Identify from a ROS 2 bag (UR's ROS 2 driver's /joint_states), no ROS installation needed.

Here the bag is made from a sample log first, as `urident convert LOG --bag DIR` does; with a
bag recorded on your robot, start at ur.load_log. Run from the repository root:
python examples/ros2_bag.py
"""

import tempfile
from pathlib import Path

import urident as ur
from urident.logs import write_bag
from urident.model import load_robot

ur5 = load_robot("ur5")
with tempfile.TemporaryDirectory() as tmp:
    for name in ("ident", "valid"):
        write_bag(ur.load_log(f"logs/sample_{name}.csv"), Path(tmp) / f"{name}_bag", ur5.joint_names)

    # A bag directory (or its .mcap / .db3 file) is a log like any other; the effort of
    # /joint_states here holds motor currents [A], as UR's released drivers publish by default.
    ident = ur.identify([Path(tmp) / "ident_bag"], robot="ur5", method="all")
    check = ur.validate(ident, [Path(tmp) / "valid_bag"])
    print(ident.report.splitlines()[0])
    print(f"consistent estimate, validated on the second bag: e_N {check.e_n:.4f}, "
          f"mean RMS {check.rms_nm.mean():.3f} N·m")
    print(check.to_json(indent=None)[:120] + " ...")
