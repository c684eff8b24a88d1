#!/usr/bin/env bash
# The README's "Your own survey", its survey file and commands as written there (300² pixels):
# an image of the asked size and pixel scale with its truth, every object drawn, the shear
# asked for. The README is read here, so a change there is tested here.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
readme=$(cd ../../.. && pwd)/README.md
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
# The survey file of the README's block (its indented `name = value` lines) and the command
# that runs it, as written there, at 300² pixels; and the shipped survey its quick start names.
python3 - "$readme" <<'PY' || fail "the README's survey block was not found"
import sys
text = open(sys.argv[1]).read()
block = text.split("## Your own survey", 1)[1].split("\n## ", 1)[0]
lines = [l.strip() for l in block.splitlines() if l.startswith("    ")]
keys = [l for l in lines if " = " in l.split("#")[0]]
commands = [l.split("  #")[0].strip() for l in lines if l.startswith("bin/shapesim-survey")]
assert len(keys) >= 8 and len(commands) == 2, (keys, commands)
open("my.survey", "w").write("\n".join(keys) + "\n")
with open("commands.sh", "w") as f:
    for c in commands:
        f.write(c.replace("bin/shapesim-", '"$BIN"/shapesim-') + " --pixels 300 -q || exit 1\n")
PY
bash commands.sh || fail "the README's survey commands failed: $(cat commands.sh)"
# Provenance keeps every value of a two-value option.
grep -qa "HIERARCH OPTION SHEAR = '0.02 0 *'" mine/image.fits || fail "OPTION SHEAR lost a value"
for d in rubin mine; do
  [ -s $d/image.fits ] && [ -s $d/truth.jsonl ] || fail "no image or truth in $d/"
done
python3 - "$tools" <<'PY' || fail "the survey image is not what the README asks for"
import json, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
cards, nx, ny, _ = read("mine/image.fits")
assert nx == ny == 300, (nx, ny)
assert abs(abs(float(cards["CD1_1"])) * 3600 - 0.2) < 1e-9, cards["CD1_1"]
objects = sum(1 for _ in open("mine/objects.jsonl"))
assert int(cards["NOBJ"]) == objects, (cards["NOBJ"], objects)
assert abs(float(cards["G1"]) - 0.02) < 1e-12, cards["G1"]
PY
exit 0
