#!/usr/bin/env bash
# report.sh OUT INPUT...: the reproduction's report.md (on stdout) from what pipelines/reproduce.mk
# wrote into OUT. Every number comes from those files; only the prose is written here.
set -euo pipefail
out=$1
shift

lines() { wc -l < "$1" | tr -d ' '; }
# Records of a catalogue whose "flags" list holds FLAG.
flagged() { grep -c "\"flags\":\[[^]]*\"$2\"" "$1" || true; }
morph_points() { grep -o '"shape":' "$1" | wc -l | tr -d ' '; }
fits_card() {  # the value of header card $2 in the first image HDU of FITS file $1
  local f=$1 card=$2
  # 80-character cards; the first HDU with NAXIS = 2 holds it (ours: extension 1).
  fold -w 80 "$f" | grep -a -m1 "^$card *=" | sed "s/^$card *= *//; s/ *\/.*//; s/'//g; s/ *$//"
}

# The objects of catalogue $1 brighter than I = $2, by real parent: "N K BEST PARENT" (objects,
# distinct parents, the most one parent supplied, that parent).
parent_counts() {
  awk -v limit="$2" 'match($0, /"mag":[-0-9.e+]+/) { m = substr($0, RSTART + 6, RLENGTH - 6) + 0;
      if (m < limit && match($0, /"parent":"[^"]*"/)) { n++; p[substr($0, RSTART + 10, RLENGTH - 11)]++ } }
    END { k = 0; best = 0; who = "–"
          for (q in p) { k++; if (p[q] > best || (p[q] == best && q < who)) { best = p[q]; who = q } }
          printf "%d %d %d %s", n, k, best, who }' "$1"
}
# "largest/all (share) from PARENT", the most any one real parent supplied.
parent_share() {
  parent_counts "$1" "$2" | awk '{ if ($1 == 0) printf "0/0"; else printf "%d/%d (%.0f%%) from %s", $3, $1, 100 * $3 / $1, $4 }'
}
# The merged run's counts, from shapesim-sample's line in the log: "D per arcmin^2 over A - B,
# SOURCE" (a count law) or "... fitted to N galaxies" (--counts fit).
counts_fit() {
  grep -a 'galaxy counts:' "$1" | tail -1 | sed 's/.*galaxy counts: //; s/ per arcmin^2 over / per arcmin² over I = /; s/ - /–/'
}
# The merged run's draw options from its command in the log ("--neighbours K --max-mag-shift S").
merged_option() { grep -a -o -- "--$2 [0-9.]*" "$1" | tail -1 | cut -d' ' -f2; }
# Over the seeds of merged.shares.txt, the largest share brighter than I = $2: "a/b (c%) … at
# seeds s…; at most 10% in k of n".
seed_shares() {
  awk -v limit="$2" '{ if (match($0, "I < " limit ": [0-9]+/[0-9]+")) {
        split(substr($0, RSTART + length("I < " limit ": "), RLENGTH - length("I < " limit ": ")), f, "/")
        share = f[2] > 0 ? f[1] / f[2] : 0; n++; if (share <= 0.1) k++
        list = list (n > 1 ? ", " : "") sprintf("%s (%.0f%%)", f[1] "/" f[2], 100 * share) } }
    END { printf "%s; at most 10%% in %d of %d", list, k, n }' "$1"
}
# A truth catalogue's galaxies that lost at least 1% of their flux where the renderer clipped
# negative model light: "k of n (p%); at most f of a galaxy's flux".
clipped_share() {
  awk 'match($0, /"kind":"galaxy"/) && match($0, /"flux":[-0-9.e+]+/) {
      f = substr($0, RSTART + 7, RLENGTH - 7) + 0; c = 0; n++
      if (match($0, /"clipped_flux":[-0-9.e+]+/)) c = substr($0, RSTART + 15, RLENGTH - 15) + 0
      if (f > 0 && c / f >= 0.01) k++
      if (f > 0 && c / f > worst) worst = c / f }
    END { printf "%d of %d (%.1f%%); at most %.2g of a galaxy'"'"'s flux", k, n, n ? 100 * k / n : 0, worst }' "$1"
}
# "N objects from K real galaxies".
bright_parents() {
  parent_counts "$1" "$2" | awk '{ printf "%d objects from %d real galaxies", $1, $2 }'
}

version=$(grep -a -m1 -o 'shapesim) [^ ]*' "$out/pipeline.log" 2>/dev/null | tail -1 | cut -d' ' -f2 || true)
sources=$(lines "$out/sources.jsonl")
models=$(lines "$out/shapelets.jsonl")
converged=$(flagged "$out/shapelets.jsonl" converged)
kept=$(morph_points "$out/morphology.json")

cat <<EOF
# Reproducing Massey et al. (2004) on the HDF-N cut

Made by \`make reproduce\` (\`pipelines/reproduce.mk\`) with shapesim ${version:-?}. Every
command, each program's own timing line and the run's wall time are in
[\`pipeline.log\`](pipeline.log); every number below is read from the files in this folder.

## Real and simulated, side by side

The HDF-N F814W cut (left), a simulation drawn from the δ-function PDF (the real galaxies
re-placed, centre) and a full simulation (new galaxies from the smoothed PDF, right), at one
pixel scale, one noise level and one grey stretch (asinh, set by the real image's noise). The
two simulations share their seed, so they place the same parents at the same positions: what
differs between them is the smoothing of the PDF alone.

![HDF | δ-function simulation | full simulation](figures/hdf_delta_sim.png)

| step | result |
|---|---|
| \`shapesim-detect\` | $sources objects above 1.3σ in the real image |
| \`shapesim-decompose\` | $models shapelet models, $converged converged (χ²_r ≤ 1 within 2σ) |
| \`shapesim-smooth\` | $kept models in the morphology PDF (not edge, bright-star, noise-dominated or a bad fit) |
| \`shapesim-sample\` + \`-render\`, like the HDF | $(lines "$out/delta.truth.jsonl") galaxies (δ), $(lines "$out/sim.truth.jsonl") (full), at the real field's density brighter than I = 29 |
| \`shapesim-sample\` + \`-render\`, $(fits_card "$out/sim6.fits" FIELDNX) × $(fits_card "$out/sim6.fits" FIELDNY) pixels | $(lines "$out/sim6.truth.jsonl") objects |
| \`shapesim-measure\` | $(lines "$out/hdf.morph.jsonl") (HDF), $(lines "$out/delta.morph.jsonl") (δ), $(lines "$out/sim.morph.jsonl") (full), $(lines "$out/sim6.morph.jsonl") (large) galaxies measured |

## The paper's Table, measured

Our rows are measured on the four images by \`shapesim-measure\` (errors: bootstrap); the
paper's rows are its own published values (\`share/data/paper/\`). Its FWHM figures are from
its text: 0.30″ / 0.24″ for the real galaxies of both HDFs, 0.31″ / 0.23″ simulated.

EOF
cat "$out/table.md"
cat <<EOF

Our C is measured within 1.5 Petrosian radii as the paper defines it, but on galaxies of the
one 512² cut, so the samples are small and much fainter on average than the paper's
catalogue of both HDFs; compare our HDF row with our simulation rows first.

How far each simulated catalogue is from the real one (two-sample Kolmogorov–Smirnov and the
1D Wasserstein distance):

EOF
cat "$out/compare/distances.md"
cat <<EOF

## The sky

The simulations' noise is the HDF sky's own, measured by \`shapesim-detect --noise-model\` on
the pixels no object of S/N ≥ 4 reaches (grown by 2 pixels, clipped at 5 MAD-σ): its rms and
2-D autocorrelation out to 8 pixels, drawn as white noise through the kernel that has that
autocorrelation, its σ varying as the HDF's weight map (\`render --noise-weight\`). Each
image's sky is measured alike (its own detection, the HDF's weight map); the KS test compares
the pixel histograms on a 4-pixel grid, each about its own median:

EOF
cat "$out/sky.md"
cat <<EOF

## A field we did not tune on: the XDF cutout

The XDF F814W cutout (ACS, 0.06″, 0.25 arcmin²) and its δ-function simulation: its own
intrinsic models re-placed at its density, drawn through its star's PSF with its own sky and
photon noise, and measured alike (I ≤ 29; C, A, Gini and M20 for I ≤ 26). The sky:

EOF
cat "$out/xdf/sky.md"
cat <<EOF

The Table:

EOF
cat "$out/xdf/table.md"
cat <<EOF

KS p of the δ against the real cutout:$(awk -F'|' '$3 ~ /xdf_delta/ && $2 ~ /^ (mag|fwhm_arcsec|e|c|a_sym|gini|m20) $/ { gsub(/ /, "", $2); gsub(/ /, "", $7); printf " %s %s;", $2, $7 }' "$out/xdf/compare/distances.md")

## The δ-function simulations at five seeds

One seed's KS p is one draw of the bootstrap and the noise. The HDF's and the XDF's δ-function
simulations at five seeds from $(head -1 "$out/seeds.md" | grep -o 'seed [0-9]*' | head -1 | cut -d' ' -f2), each drawn, rendered and measured as above and compared with its real image
(\`seeds.md\`; \`seeds/hdf/\`, \`seeds/xdf/\`):

$(cat "$out/seeds.md")

Their skies, each measured as its real field's is: the rms and the 1st, 5th, 95th and 99th
percentiles of the sky pixels over the real sky's (each rms × the sky's measured marginal at
the percentile; the noise record's \`marginal\`), and the seeds' mean of each
(\`seeds/sky.md\`):

$(cat "$out/seeds/sky.md")

## The models where they were

Each field's own fits replayed where they were fitted (\`shapesim-sample --replay\`: no draw,
no rotation), rendered with new noise at the same five seeds and measured as its δ simulations
are, every real galaxy then paired with its replays (\`shapesim-measure --compare-paired\`;
\`replays/\`). A ratio near 1 says the models are the galaxies' size; a galaxy near the limit
is found only when its new noise lifts it, as its real image was, and then looks larger. The
unpaired line compares the whole catalogues, whose extra members are replays of fits that the
real catalogue did not count (fainter than the limit there, or blended).

$(cat "$out/replays/hdf.md")

$(cat "$out/replays/xdf.md")

## The paper's figures

Number counts (Fig. 5), sizes (Fig. 6), size against magnitude (Fig. 7), ellipticities
(Fig. 8), and C–A, C–r_p, A–S (Figs. 9–11):

![number counts](compare/counts.png) ![sizes](compare/size.png) ![size against magnitude](compare/size_mag.png)
![ellipticity](compare/ellipticity.png) ![C against A](compare/c_a.png) ![C against r_p](compare/c_rp.png) ![A against S](compare/a_s.png)

## Light below zero

A galaxy's light is never negative, but a truncated, noisy shapelet fit rings below zero, and
so do perturbations of it; the renderer clips what remains. \`shapesim-smooth\` moves every
parent to its nearest shape that is nowhere negative (the δ model keeps the fits as they are),
and \`shapesim-sample\` draws each new galaxy as a mixture of real ones, which rings no deeper
than they do. Galaxies that lost at least 1% of their flux to the clip:

| simulation | clipped ≥ 1% of the flux |
|---|---|
| delta (the real fits) | $(clipped_share "$out/delta.truth.jsonl") |
| sim | $(clipped_share "$out/sim.truth.jsonl") |
| sim6 | $(clipped_share "$out/sim6.truth.jsonl") |
| merged6 | $(clipped_share "$out/merged6.truth.jsonl") |

## A larger simulation

$(fits_card "$out/sim6.fits" FIELDNX) × $(fits_card "$out/sim6.fits" FIELDNY) pixels at the HDF's scale and depth, drawn from the same PDF
(shown at 1200 pixels across). Brighter than I = 23 it holds $(bright_parents "$out/sim6.objects.jsonl" 23)
as the mixtures' shape parents: each is a new galaxy, but of the kinds a 512² cut holds, and it
holds few bright ones.

![the larger simulation](figures/sim6.png)

## Every shipped field, one model

The same 6 arcmin² field drawn from a model trained on every shipped F814W-like image: the HDF
cut (WFPC2, 0.04″), the XDF cutout (ACS, 0.06″, PSF-matched to the infrared), six COSMOS/AEGIS
cutouts of single galaxies and the four COSMOS RealGalaxyCatalogs (ACS, 0.03″). Each galaxy is
fitted through its own image's PSF (\`shapesim-decompose --psf\`, \`--real-galaxy-catalog\`:
intrinsic models), so the cameras live in one model;
\`shapesim-smooth --field\` combines the two fields' counts where each is complete
($(grep -o '"completeness":[0-9.]*' "$out/merged.json" | cut -d: -f2 | paste -sd/ -) mag) and takes the cutouts as shape-only parents (\`IMAGE=shapes\`: they
shape the draws near their magnitude but are not counted), and \`shapesim-sample --neighbours\`
draws shapes conditional on magnitude, each a mixture of $(merged_option "$out/pipeline.log" mix) real galaxies. The magnitudes come from the
I-band count law (\`--counts law\`: $(counts_fit "$out/pipeline.log")), not from
the fields' few bright galaxies' luck: each bright draw then takes the shape of one of the
$(merged_option "$out/pipeline.log" neighbours) parents nearest its magnitude, at most $(merged_option "$out/pipeline.log" max-mag-shift) mag away, its β scaled as L^0.3. Rendered through the HDF's PSF and noise, measured in
the Table above as \`merged6\`. The model has $(morph_points "$out/merged.json") parents, $(grep -o '"shape_only":true' "$out/merged.json" | grep -c .) of them shape-only, from
$(grep -c . "$out/intrinsic.jsonl") HDF, $(grep -c . "$out/xdf/intrinsic.jsonl") XDF, $(cat "$out"/stamps/{aegis?,cosmos}.jsonl | grep -c .) cutout and $(cat "$out"/cosmos/*.jsonl | grep -c .) COSMOS catalogue models fitted.

The largest share of one real parent among the galaxies brighter than each magnitude:

| brighter than | HDF model (\`sim6\`) | merged model (\`merged6\`) |
|---|---|---|
| I = 22 | $(parent_share "$out/sim6.objects.jsonl" 22) | $(parent_share "$out/merged6.objects.jsonl" 22) |
| I = 24 | $(parent_share "$out/sim6.objects.jsonl" 24) | $(parent_share "$out/merged6.objects.jsonl" 24) |
| I = 26 | $(parent_share "$out/sim6.objects.jsonl" 26) | $(parent_share "$out/merged6.objects.jsonl" 26) |

One seed's largest share is one Poisson draw. Over the ten seeds from $(head -1 "$out/merged.shares.txt" | cut -d' ' -f1) on
(\`merged.shares.txt\`), the merged model's largest share of one parent:

- brighter than I = 22: $(seed_shares "$out/merged.shares.txt" 22);
- brighter than I = 24: $(seed_shares "$out/merged.shares.txt" 24);
- brighter than I = 26: $(seed_shares "$out/merged.shares.txt" 26).

The brightest galaxy of each shipped field, fitted through its PSF as in the merged run: data |
model (as the data see it) | residual, one stretch per row. A \`bad_fit\` is left out of the model.

![the brightest galaxy of each field](figures/brightest.png)

| field | id | I | n_max | χ²_r | flags |
|---|---|---|---|---|---|
$(for row in hdf xdf aegis cosmos; do
  awk -v row="$row" '{
    match($0, /"id":"[^"]*"/); id = substr($0, RSTART + 6, RLENGTH - 7)
    match($0, /"mag":[-0-9.e+]*/); mag = substr($0, RSTART + 6, RLENGTH - 6)
    match($0, /"n_max":[0-9]*/); n = substr($0, RSTART + 8, RLENGTH - 8)
    match($0, /"chi2r":[-0-9.e+]*/); chi = substr($0, RSTART + 8, RLENGTH - 8)
    match($0, /"flags":\[[^]]*\]/); flags = substr($0, RSTART + 9, RLENGTH - 10); gsub(/"/, "", flags)
    printf "| %s | %s | %.2f | %s | %.2f | %s |\n", row, id, mag, n, chi, flags
  }' "$out/figures/brightest/$row.jsonl"
done)

## Smoothing the PDF (Fig. 3)

One real galaxy perturbed at k = 0, 1, 2, 4, 8 times the smoothing length, and the share of
draws with a hole (a pixel below −1% of the peak) over 2000 draws per k:

![perturbations](figures/perturbations.png)

EOF
cat "$out/perturbations.md"
cat <<EOF

## Inputs (SHA-256)

| file | SHA-256 |
|---|---|
EOF
sha256sum "$@" | awk '{ printf "| `%s` | `%s` |\n", $2, $1 }'
