#!/usr/bin/env bash
# shapesim-render --version: exit 0, one line "shapesim-render (shapesim) <version>" on stdout.
set -euo pipefail
prog=shapesim-render

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"
