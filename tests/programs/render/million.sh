#!/usr/bin/env bash
# A million objects on a 16384² field in under 1 GiB (issue 39): render reads its records a
# chunk of lines at a time and keeps of each only what it draws and what the truth says
# (render_record_keys), prepares them in place, and paints and writes in strips. The peak
# memory render reports (VmHWM) must stay under 1024 MiB, and every object must be drawn or
# accounted for.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
models=$(cd ../../../share/data/models && pwd)
cd "$TMPDIR"
field=(--pixels 16384 --pixel-scale 0.03 --ra 150 --dec 2)
"$BIN/shapesim-sample" -q "$models/merged.json" "${field[@]}" \
  --zero-point 25.94 --mag-limit 32.9 --density 16000 --seed 1 -o sampled.jsonl || fail "sample failed"
head -n 1000000 sampled.jsonl >objects.jsonl && rm sampled.jsonl
count=$(wc -l <objects.jsonl)
[ "$count" -eq 1000000 ] || fail "only $count objects sampled"
"$BIN/shapesim-render" objects.jsonl --psf-analytic gaussian:0.1 "${field[@]}" --noise-rms 0.01 \
  -j 2 -o image.fits 2>err || fail "render failed: $(cat err)"
summary=$(grep "objects drawn into 16384 x 16384" err) || fail "no summary: $(cat err)"
peak=$(sed 's/.*peak memory \([0-9.]*\) MiB.*/\1/' <<<"$summary")
echo "$count objects: $summary"
python3 -c "import sys; sys.exit(not float('$peak') <= 1024)" ||
  fail "render of $count objects peaked at $peak MiB (limit 1024)"
