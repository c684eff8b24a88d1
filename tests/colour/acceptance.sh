#!/usr/bin/env bash
# Issue 17's acceptance on a `make colour` report (colours.md): in every adjacent-band colour,
# the δ simulation's mean equals the real galaxies' within their errors (the offset of the
# means, in their combined bootstrap errors, at most 2), and both the δ and the full
# simulation's colour distributions agree with the real one (KS p > 0.05). The run is
# deterministic at its seed, so this is a regression test of the whole chain at that seed.
#   tests/colour/acceptance.sh out/colour/colours.md
set -euo pipefail
report=${1:?usage: acceptance.sh colours.md}
python3 - "$report" <<'PY'
import sys
rows = {}
for line in open(sys.argv[1]):
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) == 11 and cells[1] in ("delta", "sim"):
        rows[(cells[0], cells[1])] = (float(cells[4]), float(cells[6]))
colours = sorted({c for c, _ in rows})
if len(colours) != 8 or len(rows) != 16:
    sys.exit(f"{sys.argv[1]}: expected 8 colours × (delta, sim), found {sorted(rows)}")
failed = []
for c in colours:
    offset, p_delta = rows[(c, "delta")]
    _, p_sim = rows[(c, "sim")]
    print(f"{c}: δ offset {offset:+.2f}σ, KS p δ {p_delta:.3f}, full {p_sim:.3f}")
    if abs(offset) > 2.0: failed.append(f"{c} δ mean {offset:+.2f}σ from real")
    if not p_delta > 0.05: failed.append(f"{c} δ KS p {p_delta}")
    if not p_sim > 0.05: failed.append(f"{c} full simulation KS p {p_sim}")
if failed:
    sys.exit(f"{sys.argv[1]}: " + "; ".join(failed))
PY
