#include "shapesim/stellarity.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/render.hpp"
#include "shapesim/resample.hpp"
#include "shapesim/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace shapesim {

namespace {

constexpr double model_floor = 0.02;  // relative ρ★ error allowed for the PSF model itself

// A pixelised PSF whose centre sits at FITS (x, y) of the returned stamp.
struct PhasedStamp {
    ImageArray image;
    double x = 0.0, y = 0.0;
};
using PhaseRenderer = std::function<PhasedStamp(double dx, double dy)>;

PointSourceLocus locus_from(const PhaseRenderer& render, double fwhm) {
    if (!(fwhm > 0.0) || !std::isfinite(fwhm))
        throw Error("PSF FWHM must be a positive number of pixels");
    PointSourceLocus locus;
    locus.fwhm = fwhm;
    locus.r_core = 0.6 * fwhm;
    locus.r_outer = 2.0 * fwhm;
    // 4×4 sub-pixel phases spanning one pixel evenly.
    std::vector<double> ratios;
    for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
            const PhasedStamp s = render(-0.375 + 0.25 * a, -0.375 + 0.25 * b);
            const double core =
                circular_aperture_flux(s.image, nullptr, nullptr, nullptr, 0, s.x, s.y,
                                       locus.r_core).flux;
            const double outer =
                circular_aperture_flux(s.image, nullptr, nullptr, nullptr, 0, s.x, s.y,
                                       locus.r_outer).flux;
            if (!(outer > 0.0)) throw Error("PSF has no positive flux within 2 FWHM");
            ratios.push_back(core / outer);
        }
    double mean = 0.0;
    for (double r : ratios) mean += r;
    mean /= double(ratios.size());
    double var = 0.0;
    for (double r : ratios) var += (r - mean) * (r - mean);
    var /= double(ratios.size());
    locus.ratio = mean;
    locus.scatter = std::sqrt(var + std::pow(model_floor * mean, 2));
    return locus;
}

// Stamp side holding 2·r_outer plus margin, odd.
int side_for(double fwhm) { return 2 * int(std::ceil(2.0 * fwhm + 4.0)) + 1; }

// FWHM of a finely sampled image: the disc of the area above half the maximum.
double half_max_fwhm(const ImageArray& image) {
    const double peak = image.maxCoeff();
    const double area = double((image > 0.5 * peak).count());
    return 2.0 * std::sqrt(area / pi);
}

}  // namespace

PointSourceLocus gaussian_point_source_locus(double fwhm_pixels) {
    if (!(fwhm_pixels > 0.0) || !std::isfinite(fwhm_pixels))
        throw Error("seeing FWHM must be > 0");
    const double sigma = fwhm_pixels / (2.0 * std::sqrt(2.0 * std::log(2.0)));
    const int side = side_for(fwhm_pixels);
    return locus_from(
        [&](double dx, double dy) {
            const double c = (side + 1) / 2.0;
            ShapeletModel g(c + dx, c + dy, sigma, 0);
            // a_00 for unit flux: F = 2√π β a_00.
            g.at(0, 0) = Complex(1.0 / (2.0 * std::sqrt(pi) * sigma), 0.0);
            return PhasedStamp{render_stamp(g, side, side), c + dx, c + dy};
        },
        fwhm_pixels);
}

PointSourceLocus model_point_source_locus(const ShapeletModel& psf) {
    psf.validate();
    // FWHM from a 4× finer rendering about the model centre.
    constexpr int fine = 4;
    const int fine_side = 2 * int(std::ceil(4.0 * psf.beta_pix * std::sqrt(psf.n_max + 1.0) *
                                            fine)) + 1;
    ShapeletModel fine_model = psf;
    fine_model.beta_pix = psf.beta_pix * fine;
    fine_model.x = fine_model.y = (fine_side + 1) / 2.0;
    const double fwhm = half_max_fwhm(render_stamp(fine_model, fine_side, fine_side)) / fine;
    const int side = side_for(fwhm);
    return locus_from(
        [&](double dx, double dy) {
            const double c = (side + 1) / 2.0;
            ShapeletModel m = psf;
            m.x = c + dx;
            m.y = c + dy;
            return PhasedStamp{render_stamp(m, side, side), c + dx, c + dy};
        },
        fwhm);
}

PointSourceLocus image_point_source_locus(const ImageArray& psf, double psf_pixel_scale,
                                          double image_pixel_scale) {
    if (psf.size() == 0) throw Error("PSF image is empty");
    if (!psf.allFinite()) throw Error("PSF image has NaN or infinite pixels");
    if (!(psf_pixel_scale > 0.0) || !(image_pixel_scale > 0.0))
        throw Error("pixel scales must be > 0");
    if (psf_pixel_scale > image_pixel_scale * (1.0 + 1e-9))
        throw Error("PSF image is sampled more coarsely than the image");
    const double total = psf.sum();
    if (!(total > 0.0)) throw Error("PSF image has no positive flux");
    const PixelPosition centre = flux_centroid(psf);
    const double ratio = image_pixel_scale / psf_pixel_scale;
    const double fwhm = half_max_fwhm(psf) / ratio;
    const int side = side_for(fwhm);
    return locus_from(
        [&](double dx, double dy) {
            const double c = (side + 1) / 2.0;  // FITS centre of the output stamp
            // The PSF's centroid lands at (c + dx, c + dy) of the stamp, integrated over
            // each image pixel (resample.hpp).
            const ImageArray out =
                resample_pixel_integrated(psf, psf_pixel_scale, image_pixel_scale, centre,
                                          side, side, {c + dx, c + dy});
            return PhasedStamp{out / total, c + dx, c + dy};
        },
        fwhm);
}

CoreFraction core_fraction(const DetectionResult& field, const Detection& object,
                           const PointSourceLocus& locus) {
    const ApertureFlux core =
        circular_aperture_flux(field, object.label, object.x, object.y, locus.r_core);
    const ApertureFlux outer =
        circular_aperture_flux(field, object.label, object.x, object.y, locus.r_outer);
    CoreFraction out;
    if (!(outer.flux > 0.0)) {
        out.ratio = out.error = std::numeric_limits<double>::quiet_NaN();
        return out;
    }
    const double c = core.flux, o = outer.flux, r = o - c;
    const double var_core = core.error * core.error;
    const double var_annulus = std::max(0.0, outer.error * outer.error - var_core);
    out.ratio = c / o;
    out.error = std::sqrt(r * r * var_core + c * c * var_annulus) / (o * o);
    return out;
}

double stellarity(const CoreFraction& measured, const PointSourceLocus& locus) {
    if (!std::isfinite(measured.ratio) || !std::isfinite(measured.error)) return 0.5;
    const double rho = measured.ratio, star = locus.ratio;
    const double sigma = std::max(measured.error, 1e-6 * star);
    const double s2 = locus.scatter * locus.scatter + sigma * sigma;
    const double l_star =
        std::exp(-0.5 * (rho - star) * (rho - star) / s2) / std::sqrt(2 * pi * s2);
    // Galaxies are resolved: their noise-free ρ lies uniformly in [0, ρ★ − 2 s★].
    const double edge = std::max(star - 2.0 * locus.scatter, 0.05 * star);
    const double l_galaxy = (normal_cdf((edge - rho) / sigma) - normal_cdf(-rho / sigma)) / edge;
    const double sum = l_star + l_galaxy;
    if (!(sum > 0.0)) return rho > star ? 1.0 : 0.0;
    return std::clamp(l_star / sum, 0.0, 1.0);
}

}  // namespace shapesim
