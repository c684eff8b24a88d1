#!/usr/bin/env bash
# The README's example: render a reference model to FITS, fit it back. Noise-free the fit must
# return the coefficients to 1e-10; with noise the same seed gives the same bytes; a bad id is
# one stderr line, exit 1, and no output file.
set -euo pipefail
ex="$EXAMPLES/render_and_fit"
models=../../data/reference/models.jsonl

"$ex" "$models" M13 "$TMPDIR/m13.fits" >"$TMPDIR/fit.jsonl" 2>"$TMPDIR/err"
grep -q '"schema":"shapesim.shapelet/1","id":"M13"' "$TMPDIR/fit.jsonl"
err=$(sed -n 's/.*max|a_fit - a_true|\/max|a| = \([^ ]*\).*/\1/p' "$TMPDIR/err")
awk -v e="$err" 'BEGIN { exit !(e < 1e-10) }' || { echo "round-trip error $err"; exit 1; }
head -c 80 "$TMPDIR/m13.fits" | grep -q '^SIMPLE  =                    T'

"$ex" "$models" M13 "$TMPDIR/a.fits" 0.01 7 >"$TMPDIR/a.jsonl" 2>/dev/null
"$ex" "$models" M13 "$TMPDIR/b.fits" 0.01 7 >"$TMPDIR/b.jsonl" 2>/dev/null
"$ex" "$models" M13 "$TMPDIR/c.fits" 0.01 8 >"$TMPDIR/c.jsonl" 2>/dev/null
cmp "$TMPDIR/a.jsonl" "$TMPDIR/b.jsonl"
! cmp -s "$TMPDIR/a.jsonl" "$TMPDIR/c.jsonl"

rc=0
"$ex" "$models" M99 "$TMPDIR/bad.fits" >"$TMPDIR/out" 2>"$TMPDIR/err" || rc=$?
[ "$rc" -eq 1 ] && [ "$(wc -l <"$TMPDIR/err")" -eq 1 ] && [ ! -s "$TMPDIR/out" ]
grep -q "no record with id M99" "$TMPDIR/err"
[ ! -e "$TMPDIR/bad.fits" ]
