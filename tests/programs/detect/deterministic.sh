#!/usr/bin/env bash
# Two runs of shapesim-detect on the same input give the same bytes: stdout, --stars, and the
# --stamps and --segmentation files (which carry no creation time).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data/hdfn && pwd)

# Same relative output names in two folders, so the records (stamp_file) match too.
for run in a b; do
  mkdir "$TMPDIR/$run"
  (cd "$TMPDIR/$run" && "$BIN/$prog" "$data/hdfn_f814w_v2.fits" -q \
    --weight "$data/hdfn_f814w_v2_weight.fits" --zero-point 22.08 --star-threshold 0.6 \
    --stamps stamps.fits --stars stars.jsonl --segmentation seg.fits >out.jsonl) ||
    fail "run $run failed"
done
cd "$TMPDIR"
[ -s a/out.jsonl ] || fail "no output"
cmp a/out.jsonl b/out.jsonl || fail "stdout differs between runs"
cmp a/stars.jsonl b/stars.jsonl || fail "--stars differs between runs"
for f in stamps.fits seg.fits; do
  cmp a/$f b/$f || fail "$f differs between runs"
done
