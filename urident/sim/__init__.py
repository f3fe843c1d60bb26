"""Physics-simulator models of an identified arm: MJCF (MuJoCo) and URDF export, the identified
terms a format cannot express, and MuJoCo's own inverse dynamics.

* :mod:`urident.sim.mjcf` describes the exported MJCF in plain values, which
  :func:`urident.sim.mujoco_model.arm_xml` builds as a ``mujoco.MjSpec`` and writes; the URDF
  writer is :mod:`urident.ident.urdf`;
* :mod:`urident.sim.terms` says which identified terms each format can express and what share of
  a validation torque the others carry;
* :mod:`urident.sim.models` loads a user's MJCF/URDF (:mod:`urident.sim.chain`: the same chain
  when the joint axis lines agree after placing the base; :mod:`urident.sim.compare`: the model
  beside the robot file) and :mod:`urident.sim.correct` writes it corrected (MJCF via MjSpec);
* :mod:`urident.sim.mujoco_model` is **the only importer of ``mujoco``** (an optional extra),
  imported lazily with an install hint.
"""
