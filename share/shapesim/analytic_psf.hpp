// Analytic PSFs: a survey's PSF given by numbers rather than an image. Gaussian (FWHM),
// Moffat (FWHM, β: I ∝ (1 + r²/α²)^−β, α = FWHM / (2√(2^{1/β} − 1)); atmospheric seeing,
// Trujillo et al. 2001 suggest β ≈ 4.765 for Kolmogorov turbulence, ground surveys fit 2.5–5),
// and Airy with a central obscuration ε (λ/D in arcsec: I ∝ [2J₁(u)/u − ε² 2J₁(εu)/(εu)]², u =
// π r/(λ/D); a space telescope's diffraction), each optionally blurred by a Gaussian jitter
// (σ in arcsec: pointing, or charge diffusion).
//
// analytic_psf_model() samples the profile on a grid five times finer than the target pixels
// (each fine pixel the mean of 3 × 3 point values), blurs it by the jitter, and models it as
// PSF images are modelled (psf_from_oversampled: integrated over the target pixels and fitted
// with shapelets, n_max raised until max |residual| ≤ the target). What the model misses is
// reported against the profile on the same fine grid: the light outside the stamp, the FWHM
// (of the azimuthally averaged profile) and the encircled energy within 1 and 2 FWHM.
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/psf.hpp"

#include <string>

namespace shapesim {

struct AnalyticPsf {
    enum class Kind { gaussian, moffat, airy };
    Kind kind = Kind::gaussian;
    double fwhm = 0.0;          ///< arcsec (Gaussian, Moffat)
    double beta = 3.5;          ///< Moffat's index, > 1
    double lambda_over_d = 0.0; ///< arcsec (Airy)
    double obscuration = 0.0;   ///< Airy: the central obscuration's diameter over D, [0, 1)
    double jitter = 0.0;        ///< arcsec, rms of a Gaussian blur (0: none)

    /// The profile at radius r (arcsec), unnormalised (peak 1 without jitter).
    double profile(double r) const;
    /// The FWHM before jitter (arcsec): `fwhm`, or the Airy core's (numerically).
    double nominal_fwhm() const;
    /// The spec as parse_analytic_psf() reads it (jitter as ";jitter=S").
    std::string describe() const;
    /// Error (field "psf") when a number is out of range.
    void validate() const;
};

/// "gaussian:FWHM", "moffat:FWHM[,BETA]" (β 3.5 by default), "airy:LAMBDA_OVER_D[,OBSCURATION]",
/// each optionally followed by ";jitter=SIGMA" (arcsec). Error (field "psf") naming the spec.
AnalyticPsf parse_analytic_psf(const std::string& spec);

/// The profile sampled on pixels of `scale` arcsec, `side` × `side` (odd), centred on the
/// middle pixel, each pixel the mean of 3 × 3 point values times the pixel's area, jitter
/// applied; the sum is the profile's flux in the stamp (the whole profile normalised to 1:
/// closed form for Gaussian and Moffat, numerically to 200 λ/D for Airy).
ImageArray analytic_psf_image(const AnalyticPsf& psf, double scale, int side);

/// An analytic PSF modelled at `target_scale` (arcsec per pixel) and how well.
struct AnalyticPsfModel {
    PsfModel psf;                  ///< unit flux, pixels of target_scale, centred at (0, 0)
    double fine_scale = 0.0;       ///< arcsec per pixel of the fine image
    int stamp = 0;                 ///< the stamp's side at the target scale (pixels)
    double fwhm = 0.0;             ///< the profile's FWHM (jitter included), arcsec
    double fwhm_error = 0.0;       ///< model's FWHM / profile's − 1
    /// Model's − profile's encircled energy within 1 FWHM, and within 2 FWHM (fractions of
    /// the total flux; the model scaled to the light in the stamp, which it holds).
    double ee_error_1 = 0.0, ee_error_2 = 0.0;
    /// The profile's light outside the stamp (a star drawn as the model holds its flux within
    /// the stamp: 2% of an Airy's reaches beyond 12 λ/D).
    double flux_outside = 0.0;
    double residual_target = 0.0;  ///< the max |residual| target the model was fitted to
    /// The largest of |fwhm_error|, |ee_error_1|, |ee_error_2|.
    double worst_error() const;
};

/// The fit options analytic PSFs are modelled with by default: max |residual| ≤ 0.2% of the
/// peak (noise-free: the series can follow the profile closely), n_max ≤ 30.
PsfFitOptions analytic_psf_fit();

/// Model `psf` at `target_scale` (see the file comment): a stamp of at least 21 pixels,
/// reaching 4 FWHM (Gaussian), 8 FWHM (Moffat) or 12 λ/D (Airy) plus 4σ of jitter, at most
/// 201 pixels; the residual target halved (at most four times, down to 1e-4, while it helps)
/// until the FWHM and both encircled energies are within `tolerance` (worst_error(); the
/// caller reports a model that is not). Error when the spec is invalid or the fit fails.
AnalyticPsfModel analytic_psf_model(const AnalyticPsf& psf, double target_scale,
                                    const PsfFitOptions& options = analytic_psf_fit(),
                                    double tolerance = 0.01);

}  // namespace shapesim
