#!/usr/bin/env bash
# seeds.sh DIR...: for each shapesim-measure --compare folder DIR (the real catalogue first,
# then one δ-function simulation per seed, named delta<SEED>, and optionally deltapooled: the
# seeds' catalogues together), a markdown table on stdout: the KS p of each statistic per seed
# and in how many seeds it is above 0.05, the rms e per seed and in how many it lies within 2 of
# the real catalogue's bootstrap σ, and the FWHM median per seed and in how many it lies within
# 3% of the real one.
set -euo pipefail
for dir in "$@"; do
  [ -s "$dir/distances.md" ] && [ -s "$dir/table.md" ] || { echo "seeds.sh: $dir: no distances.md or table.md" >&2; exit 1; }
  awk -F'|' -v field="$(basename "$dir")" '
    function trim(s) { gsub(/^ +| +$/, "", s); return s }
    FNR == 1 { file++ }
    # distances.md: | statistic | catalogue | n | n (ref) | KS D | KS p | Wasserstein |
    file == 1 && FNR > 2 {
      stat = trim($2); cat = trim($3)
      if (!(cat in seen)) { seen[cat] = 1; cats[++ncat] = cat }
      if (!(stat in known)) { known[stat] = 1; stats[++nstat] = stat }
      p[stat, cat] = trim($7)
    }
    # table.md: | catalogue | N | <C> | rms C | <A> | rms A | <S> | rms S | rms e | ...; the first row is the real one.
    file == 2 && FNR > 2 && NF > 10 && trim($2) !~ /^paper/ {
      split(trim($10), v, " ± "); rms[trim($2)] = v[1]; err[trim($2)] = v[2]
      split(trim($11), v, " ± "); fwhm[trim($2)] = v[1]; fwhm_err[trim($2)] = v[2]
      if (!real) real = trim($2)
    }
    END {
      printf "| %s: statistic |", field
      for (i = 1; i <= ncat; i++) {
        s = cats[i]; sub(/^delta/, "", s); if (s != "pooled") s = "seed " s; printf " %s |", s
      }
      printf " above 0.05 |\n|---|"
      for (i = 1; i <= ncat; i++) printf "---|"
      printf "---|\n"
      for (j = 1; j <= nstat; j++) {
        stat = stats[j]; k = 0
        printf "| KS p, %s |", stat
        for (i = 1; i <= ncat; i++) { q = p[stat, cats[i]]; printf " %s |", q; if (q + 0 > 0.05) k++ }
        printf " %d of %d |\n", k, ncat
      }
      k = 0
      printf "| rms e (%s: %s ± %s) |", real, rms[real], err[real]
      for (i = 1; i <= ncat; i++) {
        r = rms[cats[i]]; printf " %s |", r
        d = r - rms[real]; if (d < 0) d = -d
        if (d <= 2 * err[real]) k++
      }
      printf " %d of %d within 2σ |\n", k, ncat
      k = 0
      printf "| FWHM median, ″ (%s: %s ± %s) |", real, fwhm[real], fwhm_err[real]
      for (i = 1; i <= ncat; i++) {
        f = fwhm[cats[i]]; printf " %s (%+.1f%%) |", f, 100 * (f / fwhm[real] - 1)
        d = f / fwhm[real] - 1; if (d < 0) d = -d
        if (d <= 0.03) k++
      }
      printf " %d of %d within 3%% |\n\n", k, ncat
    }' "$dir/distances.md" "$dir/table.md"
done
