"""Writes a LAZ file for mema's class tests with laspy (no code shared with mema):

    python noisy_laz.py IN.laz OUT.laz

copies IN's points, classifies every 40th point 7 (low noise) and moves it 5,000 units up, every
53rd (of the rest) 18 (high noise) and moves it 5,000 units down, flags every 97th (of the rest) withheld,
and prints, as laspy reads OUT back, `noise N withheld W points P zmax Z` (Z of the points
that are neither).
"""

import sys

import laspy
import numpy as np

out = laspy.read(sys.argv[1])
n = len(out.points)
index = np.arange(n)
low = index % 40 == 0
high = (index % 53 == 0) & ~low
withheld = (index % 97 == 0) & ~low & ~high
classification = np.array(out.classification)
classification[low] = 7
classification[high] = 18
out.classification = classification
z = np.array(out.z)
z[low] += 5000.0
z[high] -= 5000.0
out.z = z
flags = np.array(out.withheld, dtype=bool)
flags[withheld] = True
out.withheld = flags
out.write(sys.argv[2])

back = laspy.read(sys.argv[2])
cls = np.array(back.classification)
held = np.array(back.withheld, dtype=bool)
noise = (cls == 7) | (cls == 18)
clean = ~noise & ~held
print(f"noise {int(noise.sum())} withheld {int((held & ~noise).sum())} points {len(cls)} zmax {float(np.max(np.array(back.z)[clean]))!r}")
