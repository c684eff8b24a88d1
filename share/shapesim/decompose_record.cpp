// A decomposition as its shapelet record: the model in the parent image's pixels, the fit's
// flags and numbers, the source's own fields, each band's coefficients; a galaxy near a brighter
// star (decompose.hpp: shapelet_record, near_bright_star).
#include "shapesim/decompose.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/model.hpp"
#include "shapesim/moments.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

namespace shapesim {

namespace {

bool has(const std::vector<std::string>& flags, const char* flag) {
    return std::find(flags.begin(), flags.end(), flag) != flags.end();
}

// [[σ_re, σ_im], …] of a fit's coefficients, in their order.
Json coefficient_errors(const ShapeletFit& fit) {
    ShapeletModel errors = fit.model;
    set_real_parameters(errors, fit.errors());
    Json list = Json::array();
    for (const Complex& c : errors.coeffs) list.push_back(Json::array({c.real(), c.imag()}));
    return list;
}

// Fraction of the pixels within `radius` of (x, y) (stamp FITS coordinates) that the mask
// gives to a neighbour.
double masked_fraction(const Stamp& stamp, double x, double y, double radius) {
    long inside = 0, masked = 0;
    for (Eigen::Index j = 0; j < stamp.mask.rows(); ++j)
        for (Eigen::Index i = 0; i < stamp.mask.cols(); ++i) {
            if (std::hypot(double(i + 1) - x, double(j + 1) - y) > radius) continue;
            ++inside;
            if (stamp.mask(j, i) != 0.0) ++masked;
        }
    return inside > 0 ? double(masked) / double(inside) : 0.0;
}

// The frame of a model fitted through a PSF: intrinsic, and the PSF's scale and order.
void add_frame(ShapeletRecord& r, const CartesianModel& psf, double pixel_scale) {
    r.extra["frame"] = "intrinsic";
    r.extra["psf_beta"] = psf.beta_pix * pixel_scale;
    r.extra["psf_n_max"] = psf.n_max;
}

// The fit's own verdicts as flags (converged or not, n_max_cap, elliptical, bad_fit, holes,
// unsupported) and the measures behind holes and unsupported.
void add_fit_flags(ShapeletRecord& r, const Decomposition& decomposition) {
    r.flags.push_back(decomposition.converged ? "converged" : "not_converged");
    if (decomposition.stop == "n_max_cap") r.flags.push_back("n_max_cap");
    if (decomposition.elliptical) r.flags.push_back("elliptical");
    if (decomposition.bad_fit) r.flags.push_back("bad_fit");
    if (decomposition.holes) r.flags.push_back("holes");
    if (decomposition.unsupported) r.flags.push_back("unsupported");
    // Undefined (null) for a model with no positive peak or total: all hole.
    const auto finite_or_null = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
    r.extra["hole_depth"] = finite_or_null(decomposition.hole);
    r.extra["negative_light"] = finite_or_null(decomposition.negative_light);
    r.extra["unsupported_light"] = finite_or_null(decomposition.unsupported_light);
}

// The flags that need the source and its stamp: neighbour, edge, saturated and noise.
void add_source_flags(ShapeletRecord& r, const SourceRecord& source, const Stamp& stamp,
                      const Decomposition& decomposition) {
    const ShapeletFit& fit = decomposition.fit;
    const double reach = fit.model.beta_pix * std::sqrt(fit.model.n_max + 1.0);
    if (has(source.flags, "blended") ||
        masked_fraction(stamp, fit.model.x, fit.model.y, reach) > 0.05)
        r.flags.push_back("neighbour");
    // The image's edge cuts the object (its segment, or the paper's 3a + 5 square). A Kron
    // aperture running off the image ("aperture_truncated") costs detection's photometry, not
    // the model, whose flux is its own: a galaxy filling an isolated-galaxy cutout keeps it.
    if (has(source.flags, "edge") || has(source.flags, "truncated")) r.flags.push_back("edge");
    // A saturated source's pixels are clipped: no model of them is the object's.
    if (has(source.flags, "saturated")) r.flags.push_back("saturated");
    // A noise detection is judged by the noise alone: truncation's share says how well the
    // flux is known, not whether the object is there.
    const auto significant = [](double flux, double error, double truncation) {
        const double noise = std::sqrt(std::max(0.0, error * error - truncation * truncation));
        return std::isfinite(noise) && flux > 3.0 * noise;
    };
    bool detected = r.flux && significant(*r.flux, decomposition.flux_error,
                                          decomposition.truncation_error);
    for (const BandFit& b : decomposition.bands)
        detected = detected || significant(flux(b.fit.model), b.flux_error, b.truncation_error);
    if (!detected) r.flags.push_back("noise");
}

// The source's own fields, renamed source_<key> where the shapelet schema reuses the name.
void add_source_fields(ShapeletRecord& r, const SourceRecord& source) {
    const Json src = source.to_json();
    for (const auto& [key, value] : src.items()) {
        if (key == "schema" || key == "id") continue;
        const bool reused = key == "x" || key == "y" || key == "flux" || key == "flux_err" ||
                            key == "mag" ||
                            key == "flags" || key == "beta" || key == "pixel_scale" ||
                            key == "n_max" || key == "coeffs" || key == "chi2r";
        r.extra[reused ? "source_" + key : key] = value;
    }
}

// The fit's numbers: β in pixels, the flux error and truncation's share, why the search
// stopped, the shear, the fits made, each order's trial and the coefficients' errors.
void add_fit_fields(Json& e, const Decomposition& decomposition) {
    e["beta_pix"] = decomposition.fit.model.beta_pix;
    if (std::isfinite(decomposition.flux_error)) e["flux_err"] = decomposition.flux_error;
    e["flux_err_truncation"] = decomposition.truncation_error;
    e["stop"] = decomposition.stop;
    if (decomposition.elliptical) e["shear"] = Json::array({decomposition.g1, decomposition.g2});
    e["fits"] = decomposition.fits;
    Json trials = Json::array();
    for (const OrderTrial& t : decomposition.trials)
        trials.push_back(Json::array({t.n_max, t.beta_pix, t.chi2r}));
    e["trials"] = trials;
    e["coeff_errors"] = coefficient_errors(decomposition.fit);
}

// A band's coefficients, flux, magnitude and errors for the record's "bands" list.
BandCoefficients band_coefficients(const BandFit& fit, const BandLabel& label) {
    BandCoefficients b;
    b.band = label.band;
    b.coeffs = fit.fit.model.coeffs;
    b.flux = flux(fit.fit.model);
    b.flux_err = fit.flux_error;
    if (label.zero_point && *b.flux > 0.0) b.mag = *label.zero_point - 2.5 * std::log10(*b.flux);
    b.chi2r = fit.chi2r;
    b.extra["flux_err_truncation"] = fit.truncation_error;
    b.extra["coeff_errors"] = coefficient_errors(fit.fit);
    if (fit.templated) b.extra["shape"] = "stack";
    if (label.zero_point) b.extra["zero_point"] = *label.zero_point;
    return b;
}

}  // namespace

ShapeletRecord shapelet_record(const SourceRecord& source, const Decomposition& decomposition,
                               const Stamp& stamp, double pixel_scale,
                               std::optional<double> zero_point, const CartesianModel* psf,
                               const std::vector<BandLabel>& bands) {
    require(bands.size() == decomposition.bands.size(),
            "the band names do not match the joint fit's bands");
    ShapeletModel model = decomposition.fit.model;
    model.x += stamp.x0 - 1;
    model.y += stamp.y0 - 1;
    ShapeletRecord r = ShapeletRecord::from_model(model, pixel_scale, source.id);
    if (psf) add_frame(r, *psf, pixel_scale);
    r.chi2r = decomposition.chi2r;
    if (zero_point && r.flux && *r.flux > 0.0)
        r.mag = *zero_point - 2.5 * std::log10(*r.flux);
    add_fit_flags(r, decomposition);
    add_source_flags(r, source, stamp, decomposition);
    add_source_fields(r, source);
    Json& e = r.extra;
    add_fit_fields(e, decomposition);
    for (std::size_t k = 0; k < bands.size(); ++k)
        r.bands.push_back(band_coefficients(decomposition.bands[k], bands[k]));
    if (!bands.empty()) {
        e["band"] = bands.front().band;
        // The record's magnitudes are the reference band's: so is its zero point.
        if (e.contains("zero_point")) e["source_zero_point"] = e["zero_point"];
        if (zero_point) e["zero_point"] = *zero_point;
        else e.erase("zero_point");
    }
    return r;
}

bool near_bright_star(double x, double y, double reach, double galaxy_flux,
                      const std::vector<SourceRecord>& stars) {
    for (const SourceRecord& star : stars) {
        if (!(star.flux > galaxy_flux)) continue;
        double radius = 0.0;
        const auto kron = optional_double(star.extra, "kron_radius");
        if (kron && star.a) radius = *kron * *star.a;
        else if (star.fwhm) radius = 1.5 * *star.fwhm;
        // A bright star's halo reaches past its Kron aperture, as far as its isophote and, as
        // the Kron radius's wings do, beyond: light at the noise level still matters to a
        // galaxy the star outshines tenfold.
        if (const auto area = optional_double(star.extra, "iso_area");
            area && star.flux > 10.0 * galaxy_flux)
            radius = std::max(radius, std::sqrt(std::max(0.0, *area) / pi));
        if (std::hypot(star.x - x, star.y - y) < reach + 2.0 * radius) return true;
    }
    return false;
}

}  // namespace shapesim
