// Non-parametric morphology of one galaxy: Petrosian radius, concentration C, asymmetry A,
// clumpiness S, Gini and M20 (paper §5; DESIGN §5), defined as statmorph does
// (Rodriguez-Gomez et al. 2019, the community's reference implementation) so that the numbers
// can be compared with the literature; S is also given ×10 (Conselice 2003, the paper's).
//
// On a stamp (image, segmentation labels, optional bad-pixel mask; stamp pixel (i, j) is at
// x = i, y = j, 0-based, as in statmorph):
//  - masked: pixels of other segments, the mask, non-finite pixels and 10σ outliers (against
//    their 8 neighbours); Z = the stamp with masked pixels set to 0 (sky kept), Zs = Z with
//    the sky set to 0 too. Centroid from Zs.
//  - sky box: the first (row-major) square of side 32, 16, … that holds only sky and no mask;
//    its pixels of Z give the sky's mean and σ and the background terms of A and S.
//  - Petrosian radius about a centre: the root of |annulus mean (width 1)| / |disc mean| = η
//    (0.2), bracketed on 100 radii from 1 to the stamp diagonal, refined to 1e-6 (exact
//    aperture photometry, exact_aperture.hpp: sep's subpix 0 and photutils' "exact" sums, to
//    rounding). r_p about the centroid sizes the asymmetry aperture, r_p about the asymmetry
//    centre everything else.
//  - A(c) = (Σ_ap |I_180 − I| − area_unmasked · B_A) / Σ_ap |I|, aperture 1.5 r_p(centroid),
//    I_180 = I rotated by 180° about c (bilinear, zero outside), masks made symmetric;
//    B_A = Σ |B_180 − B| / N over the sky box. Minimised over c by Nelder–Mead from the
//    centroid (initial simplex ±5% of the coordinates, stop at 1e-6 in c and 1e-4 in A).
//  - C = 5 log₁₀(r80/r20), growth curve within 1.5 r_p about the asymmetry centre.
//  - S = (Σ_ann max(Z − Z_k, 0) − area · B_S) / Σ_ann Z, Z_k the k×k boxcar (k = ⌊0.25 r_p⌋,
//    reflecting edges), annulus 0.25 r_p … 1.5 r_p; B_S the same residual per sky pixel.
//    One deliberate difference from statmorph: an even k is raised to the next odd one. An
//    even window sits half a pixel off centre, so a smooth gradient leaves a one-sided residual
//    that reads as clumps and turns with the galaxy (an irregular test galaxy: 10·S = 1.78
//    with statmorph's k = 10, 0.43 with k = 11, and rotated copies then agree). On statmorph's
//    reference galaxy S moves from 0.0043 to 0.0031. `statmorph_boxcar` restores the original.
//  - Gini over the pixels of the Gini segment (Z smoothed by a Gaussian of σ = 0.2 r_p,ellip
//    above its mean in the elliptical annulus at r_p,ellip about the centroid; the connected
//    region holding the maximum); M20 = log₁₀(M of the brightest 20% of the flux / M_tot).
// Each statistic that cannot be computed is NaN with a flag naming why.
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/image.hpp"
#include "shapesim/lsq.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace shapesim {

struct MorphometryOptions {
    double eta = 0.2;                 ///< Petrosian ratio
    double annulus_width = 1.0;       ///< Petrosian annulus, pixels
    double petro_extent = 1.5;        ///< CAS aperture, × r_p
    double petro_fraction_cas = 0.25; ///< boxcar size and S inner radius, × r_p
    double petro_fraction_gini = 0.2; ///< Gini smoothing σ, × r_p,ellip
    int skybox_size = 32;             ///< first sky box side, pixels
    double n_sigma_outlier = 10.0;    ///< outlier threshold (≤ 0: none)
    /// S's boxcar exactly as statmorph's (k = ⌊0.25 r_p⌋, off centre when even); by default k
    /// is made odd so the window is centred (see the file comment).
    bool statmorph_boxcar = false;
};

struct Morphometry {
    double x_centroid = 0.0, y_centroid = 0.0;  ///< stamp pixels, 0-based
    double x_asymmetry = 0.0, y_asymmetry = 0.0;
    double r_petro_centroid = 0.0;  ///< circular Petrosian radius about the centroid
    double r_petro = 0.0;           ///< … about the asymmetry centre
    double r_petro_ellip = 0.0;     ///< elliptical, semi-major axis
    double elongation = 1.0, orientation = 0.0;  ///< about the asymmetry centre (radians)
    double r20 = 0.0, r50 = 0.0, r80 = 0.0;
    double concentration = 0.0;
    double asymmetry = 0.0;
    double smoothness = 0.0;        ///< statmorph's S (no factor 10)
    double gini = 0.0, m20 = 0.0;
    double sky_mean = 0.0, sky_sigma = 0.0;
    int sky_box = 0;                ///< side of the sky box (0: none found)
    std::vector<std::string> flags; ///< why a statistic is NaN or doubtful
    double clumpiness() const { return 10.0 * smoothness; }  ///< Conselice 2003, the paper's
};

/// The statistics of segment `label` of `labels` on `image` (same size); `mask` (non-zero =
/// bad, same size) optional. Throws Error when the sizes differ or the segment has no
/// positive flux.
Morphometry measure_morphometry(const ImageArray& image, const LabelArray& labels, int label,
                                const MaskArray* mask, const MorphometryOptions& options = {});

namespace detail {
/// A flag per pixel, row-major.
using PixelFlags = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
/// The pixels measure_morphometry leaves out (true): other segments, the mask's, non-finite
/// pixels and, for n_sigma > 0, outliers from their eight neighbours. (Exposed for its test.)
PixelFlags bad_pixels(const ImageArray& image, const LabelArray& labels, int label,
                      const MaskArray* mask, double n_sigma);

/// The asymmetry centre and its A (morphometry_asymmetry.cpp).
struct AsymmetryCentre {
    std::array<double, 2> centre;  ///< stamp pixels, 0-based
    double asymmetry;
    bool left_stamp;  ///< the search tried a centre off the stamp: `centre` is the start
};
/// A(c) in a circle of radius `r` on `z` (bad pixels zeroed, `masked` made symmetric), less
/// `sky_asymmetry` per unmasked pixel, minimised by Nelder–Mead from `start`.
AsymmetryCentre minimise_asymmetry(const ImageArray& z, const PixelFlags& masked, double r,
                                   double sky_asymmetry, const std::array<double, 2>& start);
}  // namespace detail

}  // namespace shapesim
