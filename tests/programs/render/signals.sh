#!/usr/bin/env bash
# SIGTERM, SIGINT and SIGHUP in the middle of a render (what timeout, Slurm's preemption, Ctrl-C
# and a closed terminal send) leave no temporary behind: the image's and the truth's
# `*.tmp.<pid>` are removed, one line says so, and the program dies of the signal (exit 128 + N
# through timeout --preserve-status). Issue 39.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cd "$TMPDIR"
for sig in TERM INT HUP; do
  rc=0
  timeout --preserve-status -s $sig 0.3 "$BIN/shapesim-render" --psf-analytic moffat:0.7 \
    --pixels 8000 --pixel-scale 0.2 --noise-rms 1 -q -o big.fits --truth truth.jsonl \
    </dev/null >out 2>err || rc=$?
  [ "$rc" -eq $((128 + $(kill -l $sig))) ] || fail "SIG$sig: exit $rc, $(cat err)"
  expect_error "$rc" "$rc" "^shapesim-render: \(terminated\|interrupted\|hung up\); unfinished outputs removed$"
  leftover=$(ls -A | grep -v '^out$\|^err$' || true)
  [ -z "$leftover" ] || fail "SIG$sig left: $leftover"
done
exit 0
