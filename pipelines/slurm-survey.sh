#!/usr/bin/env bash
# slurm-survey.sh [--wait] [--sbatch 'ARGS'] [VAR=VALUE ...]: run pipelines/survey.mk on Slurm,
# one array task per tile and one merge job that starts when every tile has succeeded.
#
#   pipelines/slurm-survey.sh OUT=out/survey FIELD='--area 4' TILE=2048 SEED=3
#   pipelines/slurm-survey.sh --wait --sbatch '--partition=short --mem=2G' OUT=...
#
# VAR=VALUE are survey.mk's variables (OUT, FIELD, TILE, SEED, MODEL, PSF, NOISE, MEASURE ...),
# passed unchanged to every job, so the tiles are byte for byte those of
# `make -f pipelines/survey.mk -j N` with the same variables. The grid is planned here, before
# submitting, so the jobs share nothing but read-only inputs. Run it from the repository (or
# wherever BIN= points to the programs) on a file system the compute nodes see. Job logs go
# to OUT/slurm/. A failed tile K can be rerun alone, by make (`make -f pipelines/survey.mk
# VARS task-K`) or by Slurm (`sbatch --array=K OUT/slurm/tile.sh`); its bytes come out the same.
# --wait: poll until both jobs have ended; exit 0 only if all of them COMPLETED.
set -euo pipefail

die() { echo "slurm-survey: $*" >&2; exit 1; }
wait_for_jobs=0
sbatch_args=()
while [ $# -gt 0 ]; do
  case $1 in
    --wait) wait_for_jobs=1; shift ;;
    --sbatch) [ $# -ge 2 ] || die "--sbatch needs an argument"; read -r -a sbatch_args <<<"$2"; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *=*) break ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done
for v in "$@"; do [[ $v == *=* ]] || die "expected VAR=VALUE, got '$v'"; done
command -v sbatch >/dev/null || die "sbatch not found: is this a Slurm submit host?"

here=$(cd "$(dirname "$0")" && pwd)
survey=(make --no-print-directory -f "$here/survey.mk" "$@")
"${survey[@]}" plan >/dev/null
out=$("${survey[@]}" -s print-OUT)
tiles=$(wc -l < "$out/tiles.txt")
[ "$tiles" -gt 0 ] || die "no tiles planned in $out/tiles.txt"
mkdir -p "$out/slurm"

# The job scripts hold the exact make command, quoted, and run from this directory.
quoted=$(printf '%q ' "${survey[@]}")
write_job() {  # write_job FILE TARGET
  printf '#!/usr/bin/env bash\nset -euo pipefail\ncd %q\nexec %s %s\n' "$PWD" "$quoted" "$2" > "$1"
  chmod +x "$1"
}
write_job "$out/slurm/tile.sh" 'task-$SLURM_ARRAY_TASK_ID'
write_job "$out/slurm/merge.sh" all

tile_job=$(sbatch --parsable --job-name=shapesim-tiles --array=0-$((tiles - 1)) \
  --output="$out/slurm/tile-%a.out" "${sbatch_args[@]}" "$out/slurm/tile.sh")
tile_job=${tile_job%%;*}
merge_job=$(sbatch --parsable --job-name=shapesim-merge --dependency=afterok:"$tile_job" \
  --kill-on-invalid-dep=yes --output="$out/slurm/merge.out" "${sbatch_args[@]}" "$out/slurm/merge.sh")
merge_job=${merge_job%%;*}
echo "slurm-survey: $tiles tiles in array job $tile_job, merge in job $merge_job; logs in $out/slurm/" >&2
echo "$tile_job $merge_job"
[ "$wait_for_jobs" = 1 ] || exit 0

while [ -n "$(squeue -h -o %i -j "$tile_job,$merge_job" 2>/dev/null)" ]; do sleep 1; done
states() { scontrol -o show job "$1" | grep -o 'JobState=[A-Z_]*' | cut -d= -f2 | sort -u | paste -sd, -; }
tile_states=$(states "$tile_job")
merge_states=$(states "$merge_job")
if [ "$tile_states" != COMPLETED ] || [ "$merge_states" != COMPLETED ]; then
  die "tiles: $tile_states; merge: $merge_states (logs in $out/slurm/)"
fi
echo "slurm-survey: $tiles tiles and the merge completed" >&2
