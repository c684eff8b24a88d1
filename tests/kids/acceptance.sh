#!/bin/bash
# tests/kids/acceptance.sh REPORT — the held parts of issue 49 §6 on make kids's report
# (pipelines/kids.sh) of the real KiDS r frame:
# - more than 80% of the fits converged;
# - each of the ten brightest galaxies fitted to χ²_r ≤ 1.5 or flagged (bad_fit with the stop
#   that says why: n_max_cap or flattened, or a flag of its own);
# - each fit, replayed where it was fitted and measured as the frame is, keeps its galaxy's
#   size: the paired FWHM ratio over all galaxies within 3% of 1 (it was 1.09 with the intrinsic
#   β held to the pixel), and within 5% in every magnitude quarter;
# - the δ simulation's FWHM median, its seeds pooled, within 3% of the frame's.
# The KS p of magnitude and e against the frame are reported, not held (docs/kids.md says why).
set -euo pipefail
report=${1:?usage: $0 REPORT}
[ -s "$report" ] || { echo "acceptance: $report missing or empty" >&2; exit 1; }
python3 - "$report" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
fails = []
conv = float(re.search(r"^converged_fraction ([0-9.]+)$", text, re.M).group(1))
if not conv > 0.80:
    fails.append(f"converged {conv:.3f} (needs > 0.80)")
brightest = text.split("The ten brightest galaxies")[1].split("converged_fraction")[0]
rows = [l for l in brightest.splitlines() if re.match(r"^\| \d", l)]
if len(rows) != 10:
    fails.append(f"{len(rows)} rows in the ten brightest")
for row in rows:
    c = [x.strip() for x in row.strip("|").split("|")]
    chi2r, stop, flags = float(c[3]), c[4], [f.strip() for f in c[5].split(",")]
    # Above 1.5 (or not a number): bad_fit, and why: the stop (the cap, or flattened: the noise
    # model limits) or a flag of its own (holes, unsupported, neighbour, ...).
    why = stop in ("n_max_cap", "flattened") or set(flags) - {"bad_fit", "n_max_cap", "–"}
    if "bad_fit" in flags and not why:
        fails.append(f"galaxy {c[0]}: bad_fit with no reason ({stop}; {c[5]})")
    elif "bad_fit" not in flags and not chi2r <= 1.5005:   # printed to 3 decimals
        fails.append(f"galaxy {c[0]}: chi2_r {chi2r} and no bad_fit flag ({stop}; {c[5]})")
paired = text.split("## Each fit replayed")[1].split("## The δ simulation")[0]
ratios = {}
for l in paired.splitlines():
    c = [x.strip() for x in l.strip("|").split("|")]
    if len(c) == 7 and (c[0][:1].isdigit() or c[0].startswith("all")):
        try:
            ratios[c[0]] = float(c[3].split(" ± ")[0])
        except ValueError:
            fails.append(f"paired row {c[0]}: no ratio ({c[3]})")
if len(ratios) != 5:
    fails.append(f"{len(ratios)} paired rows (four magnitude quarters and all expected)")
overall = [v for k, v in ratios.items() if k.startswith("all")]
if not overall or not abs(overall[0] - 1) <= 0.03:
    fails.append(f"paired FWHM ratio over all {overall} (needs within 3% of 1)")
for k, v in ratios.items():
    if not abs(v - 1) <= 0.05:
        fails.append(f"paired FWHM ratio {v} at {k} (needs within 5% of 1)")
table = text.split("## The δ simulation")[1]
med = {}
for l in table.splitlines():
    c = [x.strip() for x in l.strip("|").split("|")]
    if len(c) == 11 and c[0] in ("real", "pooled"):
        med[c[0]] = float(c[9].split(" ± ")[0])
delta = med["pooled"] / med["real"] - 1
if not abs(delta) <= 0.03:
    fails.append(f"δ FWHM median {med['pooled']} against {med['real']} ({delta:+.1%})")
print(f"kids: converged {conv:.1%}; paired FWHM ratio {overall[0] if overall else '?'}; "
      f"δ FWHM median {med['pooled']}\" against {med['real']}\" ({delta:+.1%})")
if fails:
    print("acceptance FAILED:\n  " + "\n  ".join(fails))
    sys.exit(1)
PY
