#!/usr/bin/env bash
# Every program on every case of the bad- and odd-input corpus (tests/corpus/): a result or one
# clean error line, never a signal, a second stderr line or a file left behind (matrix.sh
# FAILs the cell); and the outcome of each cell is the committed one (tests/corpus/matrix.md,
# whose table docs/corpus.md shows): a case that changes from a result to an error, or an error
# message that changes, is a change someone must look at (make corpus-matrix).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
corpus=$(cd ../../corpus && pwd)
"$corpus/matrix.sh" "$BIN" >"$TMPDIR/matrix.md" || fail "a cell FAILs: $(grep -F '**FAIL**' "$TMPDIR/matrix.md")"
diff -u "$corpus/matrix.md" "$TMPDIR/matrix.md" || fail "the matrix differs from tests/corpus/matrix.md"
"$corpus/readme-table.sh" --check "$TMPDIR/matrix.md" ../../../docs/corpus.md ||
  fail "docs/corpus.md's matrix is stale"
