"""Times a calibration and a model choice on TALOS's measurements with whichever build of the
package is installed (a release wheel from `pip install ./python`, or `maturin develop`). Run
from the repository's root:

    python python/bench/builds.py
"""

import time
import warnings

import armcomp

warnings.simplefilter("ignore")
robot = armcomp.Robot.load("robots/talos-left-arm.toml")
data = armcomp.Measurements.read("data/talos-left-arm/measurements.csv", robot)
start = time.perf_counter()
armcomp.calibrate(robot, data, identify="base,markers,geometry")
calibrated = time.perf_counter() - start
start = time.perf_counter()
armcomp.fit(robot, data[::2])
fitted = time.perf_counter() - start
print(f"calibrate base,markers,geometry (61 rows): {calibrated:.2f} s")
print(f"fit, default settings (even rows, 31): {fitted:.1f} s")
