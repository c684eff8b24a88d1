#!/usr/bin/env bash
# Single-pixel events (cosmic rays, hot pixels) are neither stars nor galaxies: the corpus's
# hot-pixels.fits (the 5-galaxy field, one star, 30 hot pixels of 320–900 on σ = 1) gives 5
# galaxies and 1 star to detect, a count of the events on stderr, and no event among the
# objects measure reports, even with --with-stars. (They used to be 31 "stars", which
# decompose --stars then treated as bright stars.)
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cases=$(cd ../../corpus/cases && pwd)
cd "$TMPDIR"
"$BIN/shapesim-detect" "$cases/hot-pixels.fits" --stars stars.jsonl >galaxies.jsonl 2>err ||
  fail "detect failed: $(cat err)"
[ "$(wc -l <galaxies.jsonl)" -eq 5 ] || fail "expected 5 galaxies, got $(wc -l <galaxies.jsonl)"
[ "$(wc -l <stars.jsonl)" -eq 1 ] || fail "expected 1 star, got $(wc -l <stars.jsonl)"
grep -q "single-pixel events" err || fail "no count of the events: $(cat err)"
"$BIN/shapesim-measure" -q "$cases/hot-pixels.fits" --with-stars >all.jsonl || fail "measure failed"
[ "$(wc -l <all.jsonl)" -eq 6 ] || fail "measure --with-stars: expected 6 objects, got $(wc -l <all.jsonl)"
exit 0
