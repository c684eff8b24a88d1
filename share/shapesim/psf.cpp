#include "shapesim/psf.hpp"

#include "shapesim/fits_io.hpp"
#include "shapesim/statistics.hpp"

#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/optimize.hpp"
#include "shapesim/resample.hpp"
#include "shapesim/transform.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

namespace shapesim {

namespace {

// One least-squares fit at a given ln β (fit empty and rss infinite when the fit failed).
struct Trial {
    double ln_beta = 0.0;
    double rss = std::numeric_limits<double>::infinity();
    std::optional<ShapeletFit> fit;
};

class BetaSearch {
public:
    BetaSearch(const ImageArray& image, const ImageArray& weight, int n_max)
        : image_(image), weight_(weight), n_max_(n_max) {}

    int fits() const { return fits_; }

    Trial evaluate(double ln_beta, PixelPosition centre) {
        ++fits_;
        Trial t;
        t.ln_beta = ln_beta;
        try {
            t.fit = fit_shapelets(image_, weight_, nullptr, centre.x, centre.y,
                                  std::exp(ln_beta), n_max_);
            t.rss = t.fit->residual.square().sum();
            if (!std::isfinite(t.rss)) t.rss = std::numeric_limits<double>::infinity();
        } catch (const Error&) {
            t.fit.reset();  // e.g. rank-deficient: not a candidate
        }
        return t;
    }

    // Golden-section search for the smallest RSS on [a, b] (ln β), to width `tolerance`;
    // returns the best trial seen, including `best` passed in.
    Trial golden(double a, double b, double tolerance, PixelPosition centre, Trial best) {
        auto bracket = golden_section(
            [&](double ln_beta) { return evaluate(ln_beta, centre); }, a, b, tolerance,
            [](const Trial& p, const Trial& q) { return p.rss < q.rss; },
            [&](Trial& dropped) { keep_better(best, dropped); });
        keep_better(best, bracket.fc);
        keep_better(best, bracket.fd);
        return best;
    }

    // Scan `grid` points evenly in [ln_lo, ln_hi], then refine between the best one's
    // neighbours.
    Trial scan_and_refine(double ln_lo, double ln_hi, int grid, double tolerance,
                          PixelPosition centre) {
        if (!(ln_hi - ln_lo > tolerance)) return evaluate(0.5 * (ln_lo + ln_hi), centre);
        const double step = (ln_hi - ln_lo) / (grid - 1);
        Trial best;
        int best_k = -1;
        for (int k = 0; k < grid; ++k) {
            Trial t = evaluate(ln_lo + k * step, centre);
            if (t.rss < best.rss) {
                best = std::move(t);
                best_k = k;
            }
        }
        if (best_k < 0) return best;  // every fit failed
        const double a = ln_lo + std::max(0, best_k - 1) * step;
        const double b = ln_lo + std::min(grid - 1, best_k + 1) * step;
        return golden(a, b, tolerance, centre, std::move(best));
    }

private:
    static void keep_better(Trial& best, Trial& candidate) {
        if (candidate.rss < best.rss) best = std::move(candidate);
    }

    const ImageArray& image_;
    const ImageArray& weight_;
    int n_max_;
    int fits_ = 0;
};

// Model centroid − basis centre c (NaN when the fit failed or the centroid is undefined).
Eigen::Vector2d centroid_offset(const Trial& t, PixelPosition c) {
    if (!t.fit) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
    const Moments m = moments(t.fit->model);
    return {m.x - c.x, m.y - c.y};
}

void check_options(const PsfFitOptions& o) {
    require(o.n_max_min >= 0 && o.n_max_cap >= o.n_max_min,
            "PSF fit: need 0 <= n_max_min <= n_max_cap");
    require(o.residual_target >= 0.0 && std::isfinite(o.residual_target),
            "PSF fit: residual_target must be finite and >= 0");
    require(o.beta_tolerance > 0.0 && std::isfinite(o.beta_tolerance),
            "PSF fit: beta_tolerance must be finite and > 0");
    require(o.beta_grid >= 3, "PSF fit: beta_grid must be >= 3");
    require(o.min_resolution_pixels > 0.0 && std::isfinite(o.min_resolution_pixels),
            "PSF fit: min_resolution_pixels must be finite and > 0");
    require(o.centre_iterations >= 0, "PSF fit: centre_iterations must be >= 0");
    require(o.centre_tolerance > 0.0, "PSF fit: centre_tolerance must be > 0");
}

// The PSF image's peak, after refusing an image fit_psf_image() cannot use: empty, not
// finite, no positive pixel.
double checked_peak(const ImageArray& image) {
    if (image.size() == 0) throw Error("PSF image is empty");
    if (!image.allFinite()) throw Error("PSF image has NaN or infinite pixels");
    const double data_peak = image.maxCoeff();
    if (!(data_peak > 0.0)) throw Error("PSF image has no positive pixel");
    return data_peak;
}

// One Newton step on g(c) = centroid(fit at c) − c from `centre`, where g is `offset`, with
// the Jacobian by forward differences at the fit's β: the plain iteration c ← centroid can
// overshoot and diverge (a truncated basis follows a shift of its centre only in part). The
// plain step −g when the Jacobian is unusable; at most 0.5 pixel (a trust region).
Eigen::Vector2d newton_move(BetaSearch& search, const Trial& best, PixelPosition centre,
                            const Eigen::Vector2d& offset) {
    const double h = 1e-3;
    Eigen::Matrix2d jacobian;
    for (int axis = 0; axis < 2; ++axis) {
        const PixelPosition c{centre.x + (axis == 0 ? h : 0.0), centre.y + (axis == 1 ? h : 0.0)};
        const Eigen::Vector2d o = centroid_offset(search.evaluate(best.ln_beta, c), c);
        jacobian.col(axis) = (o - offset) / h;
    }
    Eigen::Vector2d move = -offset;
    if (jacobian.allFinite() && std::abs(jacobian.determinant()) > 1e-6)
        move = -jacobian.partialPivLu().solve(offset);
    if (move.allFinite() && move.norm() > 0.5) move *= 0.5 / move.norm();
    return move;
}

// One n_max's best fit and its centroid offset (fit empty when no fit is possible).
struct PsfOrderFit {
    Trial best;
    Eigen::Vector2d offset;
};

// Order n's best fit with β in [ln_lo, ln_hi]: β scanned at `start`, then the basis centre
// moved by Newton steps (newton_move()) until it is the model's own centroid.
PsfOrderFit fit_psf_order(BetaSearch& search, PixelPosition start, double ln_lo, double ln_hi,
                          const PsfFitOptions& options) {
    PixelPosition centre = start;
    Trial best =
        search.scan_and_refine(ln_lo, ln_hi, options.beta_grid, options.beta_tolerance, centre);
    if (!best.fit) return {std::move(best), {}};
    const double step = (ln_hi - ln_lo) / (options.beta_grid - 1);
    // β search at a new centre: from scratch after a large move (the RSS minimum may have
    // jumped), else within one scan step of the current β.
    auto search_at = [&](PixelPosition c, double moved, double ln_beta) {
        if (moved > 0.05)
            return search.scan_and_refine(ln_lo, ln_hi, options.beta_grid, options.beta_tolerance,
                                          c);
        const double a = std::max(ln_lo, ln_beta - step), b = std::min(ln_hi, ln_beta + step);
        Trial start_trial = search.evaluate(ln_beta, c);
        return b - a > options.beta_tolerance
                   ? search.golden(a, b, options.beta_tolerance, c, std::move(start_trial))
                   : start_trial;
    };
    Eigen::Vector2d offset = centroid_offset(best, centre);
    for (int it = 0; it < options.centre_iterations; ++it) {
        if (!offset.allFinite() || offset.norm() < options.centre_tolerance) break;
        Eigen::Vector2d move = newton_move(search, best, centre, offset);
        if (!move.allFinite()) break;
        // Accept the step (halved up to three times) only if it shrinks the offset at the
        // current β; then search β at the new centre.
        bool accepted = false;
        for (int halving = 0; halving < 4 && !accepted; ++halving, move *= 0.5) {
            const PixelPosition c{centre.x + move.x(), centre.y + move.y()};
            const Eigen::Vector2d o = centroid_offset(search.evaluate(best.ln_beta, c), c);
            if (!(o.allFinite() && o.norm() < offset.norm())) continue;
            Trial trial = search_at(c, move.norm(), best.ln_beta);
            if (!trial.fit) continue;
            centre = c;
            best = std::move(trial);
            offset = centroid_offset(best, centre);
            accepted = true;
        }
        if (!accepted) break;
    }
    return {std::move(best), offset};
}

// The record of order n's fit: its β, centre, residuals (of the data's peak), centroid
// offset and the fits it took.
PsfFitStep psf_step(int n, const ShapeletFit& fit, double data_peak,
                    const Eigen::Vector2d& offset, int fits) {
    PsfFitStep s;
    s.n_max = n;
    s.beta_pix = fit.model.beta_pix;
    s.x = fit.model.x;
    s.y = fit.model.y;
    s.max_residual_fraction = fit.residual.abs().maxCoeff() / data_peak;
    s.rms_residual_fraction = std::sqrt(fit.residual.square().mean()) / data_peak;
    s.centroid_offset = offset.norm();
    s.fits = fits;
    return s;
}

// The chosen fit as a unit-flux PSF model, with its residuals.
PsfModel unit_flux_psf(const ShapeletFit& fit, const ImageArray& image, double data_peak,
                       const PsfFitOptions& options) {
    PsfModel out;
    out.model_flux = flux(fit.model);
    if (!(out.model_flux > 0.0) || !std::isfinite(out.model_flux))
        throw Error("PSF fit: the fitted model has no positive flux");
    out.model = fit.model;
    for (Complex& a : out.model.coeffs) a /= out.model_flux;
    out.n_max = out.model.n_max;
    out.image = fit.model_image / out.model_flux;
    out.residual = fit.residual / out.model_flux;
    out.peak = data_peak / out.model_flux;
    out.data_flux = image.sum();
    out.max_residual_fraction = fit.residual.abs().maxCoeff() / data_peak;
    out.rms_residual_fraction = std::sqrt(fit.residual.square().mean()) / data_peak;
    out.reached_target = out.max_residual_fraction <= options.residual_target;
    return out;
}

// What lies beyond the model's reach r > β√(n_max+1): the data's flux there (of the total)
// and the largest |residual| (of the peak).
void measure_beyond_reach(PsfModel& out, const ImageArray& image, const ImageArray& residual,
                          double data_peak) {
    const double reach = out.model.beta_pix * std::sqrt(out.n_max + 1.0);
    double beyond_flux = 0.0, beyond_max = 0.0;
    for (int j = 0; j < int(image.rows()); ++j)
        for (int i = 0; i < int(image.cols()); ++i)
            if (std::hypot(fits_x_of_column(i) - out.model.x, fits_y_of_row(j) - out.model.y) >
                reach) {
                beyond_flux += image(j, i);
                beyond_max = std::max(beyond_max, std::abs(residual(j, i)));
            }
    out.beyond_reach_flux_fraction = beyond_flux / out.data_flux;
    out.beyond_reach_max_residual_fraction = beyond_max / data_peak;
}

}  // namespace

PsfModel fit_psf_image(const ImageArray& image, const PsfFitOptions& options) {
    check_options(options);
    const double data_peak = checked_peak(image);
    const PixelPosition start_centre = flux_centroid(image);  // throws when Σ ≤ 0

    const int nx = int(image.cols()), ny = int(image.rows());
    const double half_stamp = 0.5 * std::min(nx, ny);
    const ImageArray weight = ImageArray::Ones(ny, nx);

    // n_max raised until the residual target is met; the order of least max |residual| kept.
    std::vector<PsfFitStep> steps;
    std::optional<ShapeletFit> chosen;
    double chosen_max = std::numeric_limits<double>::infinity();
    for (int n = options.n_max_min; n <= options.n_max_cap; ++n) {
        const double root = std::sqrt(n + 1.0);
        const double ln_lo = std::log(options.min_resolution_pixels * root);
        const double ln_hi = std::log(half_stamp / root);
        if (ln_lo > ln_hi) break;  // the basis can no longer be both resolved and in the stamp
        // Every n_max starts from the flux centroid: a lower order's model centroid can be far
        // off (a poor model's centroid is), and re-centring from there need not come back.
        BetaSearch search(image, weight, n);
        PsfOrderFit order = fit_psf_order(search, start_centre, ln_lo, ln_hi, options);
        if (!order.best.fit) break;  // no fit possible (too few pixels for the coefficients)
        const PsfFitStep s = psf_step(n, *order.best.fit, data_peak, order.offset, search.fits());
        steps.push_back(s);
        if (s.max_residual_fraction < chosen_max) {
            chosen_max = s.max_residual_fraction;
            chosen = std::move(order.best.fit);
        }
        if (s.max_residual_fraction <= options.residual_target) break;
    }
    if (!chosen)
        throw Error("PSF fit: no n_max admits a beta for a " + std::to_string(nx) + "x" +
                    std::to_string(ny) + " stamp");
    PsfModel out = unit_flux_psf(*chosen, image, data_peak, options);
    measure_beyond_reach(out, image, chosen->residual, data_peak);
    out.steps = std::move(steps);
    return out;
}

ImageArray convolve_boxes(const ImageArray& fine, double fine_scale,
                          const std::vector<double>& boxes_arcsec) {
    ImageArray smoothed = fine;
    for (double box : boxes_arcsec) {
        if (!(box > 0.0) || !std::isfinite(box))
            throw Error("PSF: box widths must be finite and > 0 arcsec, got " +
                        std::to_string(box));
        smoothed = box_convolve(smoothed, box / fine_scale);
    }
    return smoothed;
}

PsfImage read_psf_image(const std::string& path, std::optional<double> pixel_scale) {
    FitsReader fits(path, FitsStart::first_image);
    PsfImage out;
    if (pixel_scale) {
        out.pixel_scale = *pixel_scale;
    } else {
        // PIXSCALE (TinyTim, WebbPSF), else the WCS of a PSF cut from a field image.
        const auto header = fits.optional_double("PIXSCALE");
        if (header)
            out.pixel_scale = *header;
        else if (has_wcs(fits))
            out.pixel_scale = read_wcs(fits).pixel_scale_arcsec();
        else
            throw Error("no PIXSCALE keyword or WCS: give the PSF's pixel scale", fits.place());
    }
    if (!(out.pixel_scale > 0.0)) throw Error("PSF pixel scale must be > 0", fits.place());
    out.pixels = fits.read_image();
    // A star cut from a field sits on the sky (a ground-based frame keeps its sky): the median
    // of the image's outermost pixels is that level, removed here, so the shapelet fit and
    // the stellarity locus both see the star alone. A model PSF's ring holds only faint wings
    // (TinyTim's at 1.5″: ~1e−6 of the peak). Non-finite pixels are left to the callers.
    if (out.pixels.allFinite()) {
        out.sky = border_median(out.pixels);
        out.pixels -= out.sky;
    }
    return out;
}

double border_median(const ImageArray& image) {
    std::vector<double> ring;
    const Eigen::Index ny = image.rows(), nx = image.cols();
    for (Eigen::Index j = 0; j < ny; ++j)
        for (Eigen::Index i = 0; i < nx; ++i)
            if (j == 0 || i == 0 || j == ny - 1 || i == nx - 1) ring.push_back(image(j, i));
    return ring.empty() ? 0.0 : median_of_values(std::move(ring));
}

PsfModel psf_from_oversampled(const ImageArray& fine, double fine_scale, double target_scale,
                              const std::vector<double>& boxes_arcsec, int stamp_pixels,
                              const PsfFitOptions& options) {
    if (!(fine_scale > 0.0) || !std::isfinite(fine_scale) || !(target_scale > 0.0) ||
        !std::isfinite(target_scale))
        throw Error("PSF: pixel scales must be finite and > 0");
    if (stamp_pixels < 3 || stamp_pixels % 2 == 0)
        throw Error("PSF: the stamp size must be odd and >= 3, got " +
                    std::to_string(stamp_pixels));
    if (fine.size() == 0) throw Error("PSF image is empty");
    if (!fine.allFinite()) throw Error("PSF image has NaN or infinite pixels");
    const ImageArray smoothed = convolve_boxes(fine, fine_scale, boxes_arcsec);
    const PixelPosition centroid = flux_centroid(smoothed);
    const double c = 0.5 * (stamp_pixels + 1);
    const ImageArray stamp = resample_pixel_integrated(
        smoothed, fine_scale, target_scale, centroid, stamp_pixels, stamp_pixels, {c, c});
    PsfModel out = fit_psf_image(stamp, options);
    out.flux_outside_stamp = 1.0 - stamp.sum() / smoothed.sum();
    return out;
}

ShapeletRecord psf_record(const PsfModel& psf, double pixel_scale, std::string id) {
    ShapeletRecord r = ShapeletRecord::from_model(psf.model, pixel_scale, std::move(id));
    r.flags.push_back(psf.reached_target ? "converged" : "residual_above_target");
    r.extra["psf_max_residual"] = psf.max_residual_fraction;
    r.extra["psf_rms_residual"] = psf.rms_residual_fraction;
    if (std::isfinite(psf.flux_outside_stamp))
        r.extra["psf_flux_outside_stamp"] = psf.flux_outside_stamp;
    return r;
}

ShapeletModel read_psf_model(const std::string& path, double pixel_scale) {
    JsonlReader reader(path, {ShapeletRecord::schema});
    ShapeletRecord record;
    if (!reader.next_record(record)) throw Error("no PSF record", path);
    ShapeletModel model = record.to_model();
    if (record.pixel_scale != pixel_scale) model = dilate(model, record.pixel_scale / pixel_scale);
    const double f = flux(model);
    if (!(f > 0.0)) throw Error("the PSF has no positive flux", path, reader.line());
    for (auto& c : model.coeffs) c /= f;
    model.x = model.y = 0.0;
    return model;
}

}  // namespace shapesim
