#!/usr/bin/env bash
# The README's "Your own survey", its commands as written there (an intrinsic model of the HDF
# cut standing in for make reproduce's merged.json, 1 arcmin² for 25): an image of the asked
# size and pixel scale with its truth, every object drawn, through the Moffat asked for. The
# README's commands are read from it, so a change there is tested here.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
readme=$(cd ../../.. && pwd)/README.md
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_sources
"$BIN/shapesim-decompose" --psf-image "$HDF_DATA/wfpc2_f814w_tinytim_psf.fits" \
  --like "$HDF_IMAGE" --psf-box 0.0996 0.05 -q >psf.jsonl || fail "PSF mode failed"
"$BIN/shapesim-decompose" -q -j 2 --psf psf.jsonl <sources.jsonl >intrinsic.jsonl ||
  fail "intrinsic fits failed"
"$BIN/shapesim-smooth" -q --like "$HDF_IMAGE" <intrinsic.jsonl >merged.json || fail "smooth failed"
# The two commands of the README's block, joined across their continuation lines, run with the
# model and the programs here and 1 arcmin².
python3 - "$readme" >commands.sh <<'PY' || fail "the README's survey commands were not found"
import re, sys
text = open(sys.argv[1]).read()
block = text.split("## Your own survey", 1)[1].split("## ", 1)[0]
lines = [l.strip() for l in block.splitlines() if l.startswith("    ")]
commands, current = [], ""
for l in lines:
    current += l.rstrip("\\").strip() + " "
    if not l.endswith("\\"):
        commands.append(current.strip())
        current = ""
commands = [c for c in commands if c.startswith("bin/shapesim-sample") or c.startswith("bin/shapesim-render")]
assert len(commands) == 2, commands
for c in commands:
    c = c.replace("bin/shapesim-", '"$BIN"/shapesim-').replace("out/reproduce/merged.json", "merged.json")
    c = c.replace("--area 25", "--area 1")
    print(c + " -q || exit 1")
PY
bash commands.sh || fail "the README's survey commands failed: $(cat commands.sh)"
[ -s my_survey.fits ] && [ -s truth.jsonl ] || fail "no image or truth"
python3 - "$tools" <<'PY' || fail "the survey image is not what the README asks for"
import json, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
cards, nx, ny, _ = read("my_survey.fits")
assert nx == ny == 300, (nx, ny)  # 1 arcmin at 0.2″
assert abs(abs(float(cards["CD1_1"])) * 3600 - 0.2) < 1e-9, cards["CD1_1"]
objects = sum(1 for _ in open("objects.jsonl"))
assert int(cards["NOBJ"]) == objects, (cards["NOBJ"], objects)
PY
exit 0
