"""A tool's mass, centre of mass and inertia on an identified UR10e, from a run with the tool and
a run of the same motion without it (a tare).

The shared recordings of a real UR10e carry such a pair. Run from the repository root:
python examples/payload.py [DATA_DIR]
"""

import sys
import tempfile
from pathlib import Path

import urident as ur

data = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/ur10e-dynamic-calibration")
csv = {"format": "dynamic_calibration"}

# 1. The arm, identified on its excitation run (the preset for real arms, physically consistent).
arm = ur.identify([ur.load_log(data / "ur-20_02_10-30sec_12harm.csv", robot="ur10e", rows=(635, 3510), **csv)],
                  robot="ur10e", method="consistent", preset="real-robot")

# 2. The tool: loaded run, and the unloaded run of the same motion as its tare.
loaded = ur.load_log(data / "ur-20_01_31-load.csv", robot="ur10e", rows=(345, 1890), **csv)
tare = ur.load_log(data / "ur-20_01_31-unload.csv", robot="ur10e", rows=(199, 1744), **csv)
tool = ur.identify_payload([loaded], arm, unloaded=[tare])

p = tool.payload                      # a urident.model.payload.Payload, UR's flange frame, SI units
print(f"mass {p.mass_kg:.3f} kg, centre of mass [{', '.join(f'{1000 * c:.1f}' for c in p.com_m)}] mm")
print("identifiable:", ", ".join(p.identifiable))
print(f"fit e_N: arm alone {tool.e_n_arm_alone:.4f}, with the tool {tool.e_n_with_payload:.4f}")
print(p.urscript())                   # the line that declares the tool to the controller
with tempfile.TemporaryDirectory() as out:   # the file `urident payload --out` writes
    tool.save(Path(out) / "tool.yaml")
    print("payload file written; JSON keys:", ", ".join(tool.to_dict()))
