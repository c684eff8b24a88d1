#!/usr/bin/env bash
# A 4-tile survey through a real one-node Slurm cluster (.ci/slurm.sh: Debian's slurmctld,
# slurmd and munge, started here and stopped at exit) equals the same survey run by
# `make -j 2`, byte for byte: every tile, the merged truth and the index. Then a tile is
# deleted and rerun alone as one array task: the same bytes again. Run by `make slurm-test`
# (CI), as root. Needs the programs built (bin/).
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
source .ci/slurm.sh
trap slurm_stop EXIT
trap 'exit 130' INT TERM
work=$(mktemp -d /tmp/shapesim-slurm.XXXXXX)
chmod 0755 "$work"
cleanup() { rc=$?; slurm_stop; rm -rf "$work"; exit "$rc"; }
trap cleanup EXIT

slurm_install
slurm_start

# The inputs, made by the reproduction's own rules: the HDF morphology, PSF and noise.
make --no-print-directory -f pipelines/reproduce.mk OUT="$work/r" \
  "$work/r/morphology.json" "$work/r/psf.jsonl" "$work/r/sources.jsonl" >"$work/inputs.log" 2>&1 ||
  { cat "$work/inputs.log"; exit 1; }
vars=(MODEL="$work/r/morphology.json" PSF="$work/r/psf.jsonl"
      "NOISE=--noise-like $work/r/sources.jsonl --gain 865200"
      "FIELD=--size 0.5 0.5 --pixel-scale 0.03985" TILE=400 SEED=11)

start=$SECONDS
make --no-print-directory -f pipelines/survey.mk -j 2 "${vars[@]}" OUT="$work/local" >"$work/local.log" 2>&1 ||
  { tail -n 20 "$work/local.log"; exit 1; }
log "make -j 2: $((SECONDS - start)) s"
[ "$(wc -l <"$work/local/tiles.txt")" = 4 ] || { echo "expected 4 tiles"; cat "$work/local/tiles.txt"; exit 1; }

start=$SECONDS
pipelines/slurm-survey.sh --wait "${vars[@]}" OUT="$work/slurm"
log "Slurm: $((SECONDS - start)) s"

compare() {
  local f
  for f in tiles/tile-000-000.fits tiles/tile-001-000.fits tiles/tile-000-001.fits tiles/tile-001-001.fits \
           tiles/tile-000-000.truth.jsonl truth.jsonl index.jsonl; do
    cmp "$work/local/$f" "$work/slurm/$f" || { echo "FAIL: $f differs between make -j and Slurm ($1)"; exit 1; }
  done
}
compare "first run"
grep -h 'peak memory' "$work"/slurm/slurm/tile-*.out | sed 's/.*peak memory/peak memory/' | sort | uniq -c

# A lost tile, rerun alone as one array task.
rm "$work/slurm/tiles/tile-001-000.fits"
job=$(sbatch --parsable --array=1 --output="$work/slurm/slurm/rerun-%a.out" "$work/slurm/slurm/tile.sh")
slurm_wait 300 "the rerun of tile 1" jobs_gone "$job"
[ "$(job_states "$job")" = COMPLETED ] || { echo "FAIL: rerun $(job_states "$job")"; exit 1; }
compare "tile 1 rerun"
echo "slurm survey: 4 tiles identical to make -j 2; a rerun tile identical"
