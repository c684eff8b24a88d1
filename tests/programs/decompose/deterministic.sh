#!/usr/bin/env bash
# shapesim-decompose gives the same bytes whatever the thread count: -j 1 and -j 2 on the
# shipped HDF-N cut (after shapesim-detect) write identical records and --models files.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-decompose

cd "$TMPDIR"
hdf_sources
[ -s sources.jsonl ] || fail "no sources from shapesim-detect"
for j in 1 2; do
  "$BIN/$prog" -q -j "$j" --stamps stamps.fits --models "models$j.fits" <sources.jsonl \
    >"shapelets$j.jsonl" || fail "-j $j failed"
done
[ -s shapelets1.jsonl ] || fail "no records"
cmp -s shapelets1.jsonl shapelets2.jsonl ||
  fail "-j 1 and -j 2 records differ: $(diff shapelets1.jsonl shapelets2.jsonl | head -c 400)"
cmp -s models1.fits models2.fits ||
  fail "-j 1 and -j 2 --models files differ"
