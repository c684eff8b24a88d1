#!/usr/bin/env bash
# Issue 49's ellipticity acceptance on a `make shapes` report (out/shapes/report.md): over the
# isolated galaxies brighter than I = 25 on five seeds of `shapesim-survey acs-f814w`, the rms
# PSF-corrected distortion per component (pooled) within 10% of the real COSMOS/AEGIS stamps',
# and their |e| distributions alike (KS p > 0.05), both measured by shapesim-measure
# --shear-estimate. The run is deterministic at its seeds: a regression test of the whole chain.
#   tests/shapes/acceptance.sh out/shapes/report.md
set -euo pipefail
report=${1:?usage: acceptance.sh report.md}
python3 - "$report" <<'PY'
import sys
row = None
for line in open(sys.argv[1]):
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) == 10 and cells[0] == "all" and cells[1] == "sim/real":
        row = cells
if row is None:
    sys.exit(f"{sys.argv[1]}: no 'all | sim/real' row")
ratio = float(row[7].split()[0])
p = float(row[9])
print(f"ellipticity: sim/real rms {ratio:.3f} (0.9-1.1), |e| KS p {p:.3g} (> 0.05)")
if not (0.9 <= ratio <= 1.1 and p > 0.05):
    sys.exit("ellipticity acceptance failed")
PY
