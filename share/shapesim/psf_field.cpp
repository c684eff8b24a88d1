#include "shapesim/psf_field.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/optimize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace shapesim {

namespace {

// x̃^i ỹ^j over i + j ≤ degree, j outer, i inner (PSFEx's order).
std::vector<double> monomials(int degree, double u, double v) {
    std::vector<double> t;
    t.reserve(std::size_t((degree + 1) * (degree + 2) / 2));
    double vj = 1.0;
    for (int j = 0; j <= degree; ++j, vj *= v) {
        double ui = 1.0;
        for (int i = 0; i + j <= degree; ++i, ui *= u) t.push_back(ui * vj);
    }
    return t;
}

// Integrals of B_n(·; β) over a box one image pixel wide about each sample: rows n, columns
// samples; sample s at (s − centre) × step image pixels from the model centre.
Eigen::MatrixXd box_integrals(int n_max, double beta, int samples, int centre, double step) {
    Eigen::MatrixXd m(n_max + 1, samples);
    std::vector<double> out(std::size_t(n_max + 1));
    for (int s = 0; s < samples; ++s) {
        const double x = (s - centre) * step;
        hermite_integrals((x - 0.5) / beta, (x + 0.5) / beta, n_max, out.data());
        for (int n = 0; n <= n_max; ++n) m(n, s) = std::sqrt(beta) * out[std::size_t(n)];
    }
    return m;
}

struct Trial {
    double cost = std::numeric_limits<double>::infinity();  // Σ residual² over the places
    double worst = std::numeric_limits<double>::infinity();  // max |residual| / peak there
    double beta = 0.0;
    Eigen::MatrixXd coeffs;  // (number of (n1, n2)) × K
};

// The fit of every component at (n_max, β): one least-squares solve with K right-hand sides.
Trial fit_at(const PsfexModel& m, const Eigen::MatrixXd& data, const Eigen::MatrixXd& places,
             const Eigen::VectorXd& peaks, int n_max, double beta) {
    const int w = int(m.components[0].cols()), h = int(m.components[0].rows());
    const Eigen::MatrixXd ix = box_integrals(n_max, beta, w, w / 2, m.sampling);
    const Eigen::MatrixXd iy = box_integrals(n_max, beta, h, h / 2, m.sampling);
    const int count = (n_max + 1) * (n_max + 2) / 2;
    Eigen::MatrixXd a(w * h, count);
    int c = 0;
    for (int n1 = 0; n1 <= n_max; ++n1)
        for (int n2 = 0; n1 + n2 <= n_max; ++n2, ++c)
            for (int row = 0; row < h; ++row)
                for (int col = 0; col < w; ++col) a(row * w + col, c) = ix(n1, col) * iy(n2, row);
    Trial t;
    t.beta = beta;
    t.coeffs = a.colPivHouseholderQr().solve(data);
    const Eigen::MatrixXd at_places = (data - a * t.coeffs) * places;  // residual at each place
    t.cost = at_places.squaredNorm();
    t.worst = 0.0;
    for (int p = 0; p < at_places.cols(); ++p)
        t.worst = std::max(t.worst, at_places.col(p).cwiseAbs().maxCoeff() / peaks(p));
    return t;
}

}  // namespace

std::vector<double> PsfVariation::terms(double x, double y) const {
    return monomials(degree, (x - x_zero) / x_scale, (y - y_zero) / y_scale);
}

bool PsfVariation::within_stars(double x, double y) const {
    return degree == 0 ||
           (std::abs(x - x_zero) <= 0.5 * x_scale && std::abs(y - y_zero) <= 0.5 * y_scale);
}

PsfexModel read_psfex(const std::string& path) {
    FitsReader fits(path);
    if (!fits.has_hdu("PSF_DATA"))
        throw Error("no PSF_DATA table: not a PSFEx model (psfex's .psf file)", path);
    fits.move_to("PSF_DATA");
    const std::string place = fits.place();
    PsfexModel m;
    // No context (psfex's PSFVAR_DEGREES 0 or too few stars): one PSF for the whole field.
    const long long axes = fits.required_int("POLNAXIS");
    if (axes != 0 && (axes != 2 || fits.required_int("POLNGRP") != 1))
        throw Error("the PSF varies with " + std::to_string(axes) + " context parameters in " +
                        std::to_string(fits.optional_int("POLNGRP").value_or(0)) +
                        " groups: shapesim reads two image coordinates in one group (psfex's "
                        "PSFVAR_KEYS X_IMAGE,Y_IMAGE, the default)",
                    place, 0, "POLNAXIS");
    auto image_coordinate = [](const std::string& name, char axis) {
        return !name.empty() && std::toupper(static_cast<unsigned char>(name[0])) == axis &&
               name.size() >= 5 && name.substr(name.size() - 5) == "IMAGE";
    };
    long long degree = 0;
    if (axes == 2) {
        m.x_name = fits.required_string("POLNAME1");
        m.y_name = fits.required_string("POLNAME2");
        if (!image_coordinate(m.x_name, 'X') || !image_coordinate(m.y_name, 'Y'))
            throw Error("the PSF varies with " + m.x_name + ", " + m.y_name +
                            ", not image coordinates (X*_IMAGE, Y*_IMAGE)",
                        place, 0, "POLNAME1");
        degree = fits.required_int("POLDEG1");
        if (degree < 0 || degree > 10)
            throw Error("POLDEG1 " + std::to_string(degree) + " is not 0 to 10", place, 0,
                        "POLDEG1");
        m.variation.x_zero = fits.required_double("POLZERO1");
        m.variation.y_zero = fits.required_double("POLZERO2");
        m.variation.x_scale = fits.required_double("POLSCAL1");
        m.variation.y_scale = fits.required_double("POLSCAL2");
    }
    m.variation.degree = int(degree);
    m.sampling = fits.required_double("PSF_SAMP");
    for (const auto& [key, value] : {std::pair{"POLSCAL1", m.variation.x_scale},
                                     {"POLSCAL2", m.variation.y_scale},
                                     {"PSF_SAMP", m.sampling}})
        if (!(std::isfinite(value) && value > 0.0))
            throw Error(std::string(key) + " is not > 0", place, 0, key);
    if (!std::isfinite(m.variation.x_zero) || !std::isfinite(m.variation.y_zero))
        throw Error("POLZERO1/2 are not finite", place, 0, "POLZERO1");
    if (fits.required_int("PSFNAXIS") != 3)
        throw Error("PSFNAXIS is not 3", place, 0, "PSFNAXIS");
    const long long w = fits.required_int("PSFAXIS1"), h = fits.required_int("PSFAXIS2");
    const long long k = fits.required_int("PSFAXIS3");
    if (w < 3 || h < 3 || w > 1024 || h > 1024 || w % 2 == 0 || h % 2 == 0)
        throw Error("the PSF stamp is " + std::to_string(w) + " x " + std::to_string(h) +
                        " samples: shapesim reads odd sizes from 3 to 1023 (psfex's PSF_SIZE)",
                    place, 0, "PSFAXIS1");
    if (k != (degree + 1) * (degree + 2) / 2)
        throw Error("PSFAXIS3 " + std::to_string(k) + " is not (POLDEG1+1)(POLDEG1+2)/2", place,
                    0, "PSFAXIS3");
    const std::vector<double> cell = fits.read_cell("PSF_MASK", 1, w * h * k);
    if ((long long)cell.size() != w * h * k)
        throw Error("PSF_MASK holds " + std::to_string(cell.size()) + " values, not PSFAXIS1 x "
                    "PSFAXIS2 x PSFAXIS3", place, 0, "PSF_MASK");
    for (double v : cell)
        if (!std::isfinite(v)) throw Error("PSF_MASK holds a value that is not finite", place, 0,
                                           "PSF_MASK");
    for (long long c = 0; c < k; ++c) {
        ImageArray b(h, w);
        for (long long row = 0; row < h; ++row)
            for (long long col = 0; col < w; ++col)
                b(row, col) = cell[std::size_t((c * h + row) * w + col)];
        m.components.push_back(std::move(b));
    }
    return m;
}

ImageArray psfex_image(const PsfexModel& model, double x, double y) {
    const std::vector<double> t = model.variation.terms(x, y);
    ImageArray out = ImageArray::Zero(model.components[0].rows(), model.components[0].cols());
    for (std::size_t k = 0; k < t.size(); ++k) out += t[k] * model.components[k];
    return out;
}

PsfField fit_psf_field(const PsfexModel& m, const PsfFieldOptions& o) {
    if (m.components.empty()) throw Error("the PSFEx model has no components");
    if (o.n_max_min < 0 || o.n_max_cap < o.n_max_min || o.n_max_cap > 40 ||
        !(o.residual_target > 0) || !(o.min_resolution_pixels > 0) || !(o.beta_tolerance > 0))
        throw Error("fit_psf_field: inconsistent options");
    const int w = int(m.components[0].cols()), h = int(m.components[0].rows());
    const int kk = int(m.components.size());
    Eigen::MatrixXd data(w * h, kk);
    for (int k = 0; k < kk; ++k)
        for (int row = 0; row < h; ++row)
            for (int col = 0; col < w; ++col)
                data(row * w + col, k) = m.components[std::size_t(k)](row, col);
    if (!std::isfinite(data.squaredNorm()))
        throw Error("the PSFEx model's samples are out of range (their squares overflow)");
    // The 3 × 3 places across the stars' range, as term weights (K × 9), and the peak there.
    Eigen::MatrixXd places(kk, 9);
    Eigen::VectorXd peaks(9);
    for (int p = 0; p < 9; ++p) {
        const std::vector<double> t =
            monomials(m.variation.degree, 0.5 * (p % 3 - 1), 0.5 * (p / 3 - 1));
        for (int k = 0; k < kk; ++k) places(k, p) = t[std::size_t(k)];
        peaks(p) = (data * places.col(p)).maxCoeff();
        if (!(peaks(p) > 0))
            throw Error("PSFEx's PSF has no positive sample at a place across its stars' range");
    }
    const double half = 0.5 * std::min(w, h) * m.sampling;  // the stamp's half-side, pixels
    Trial best;
    int best_n = -1;
    for (int n = o.n_max_min; n <= o.n_max_cap; ++n) {
        const double lo = std::log(o.min_resolution_pixels * std::sqrt(n + 1.0));
        const double hi = std::log(half / std::sqrt(n + 1.0));
        if (!(hi > lo)) break;
        auto trial = [&](double log_beta) {
            return fit_at(m, data, places, peaks, n, std::exp(log_beta));
        };
        // A scan over ln β, then golden section about its best point.
        constexpr int scan = 12;
        Trial at_n;
        int at = 0;
        for (int s = 0; s < scan; ++s) {
            Trial t = trial(lo + (hi - lo) * s / (scan - 1));
            if (t.cost < at_n.cost) { at_n = std::move(t); at = s; }
        }
        const double step = (hi - lo) / (scan - 1);
        const double a = lo + step * std::max(0, at - 1),
                     b = lo + step * std::min(scan - 1, at + 1);
        auto less = [](const Trial& x, const Trial& y) { return x.cost < y.cost; };
        auto keep = [&](const Trial& t) { if (t.cost < at_n.cost) at_n = t; };
        const GoldenBracket<Trial> last = golden_section(trial, a, b, o.beta_tolerance, less, keep);
        keep(last.fc);
        keep(last.fd);
        if (best_n < 0 || at_n.worst < best.worst) { best = at_n; best_n = n; }
        if (at_n.worst <= o.residual_target) break;
    }
    if (best_n < 0) throw Error("the PSFEx stamp is too small for any shapelet order");
    if (!std::isfinite(best.cost) || best.coeffs.size() == 0)
        throw Error("the PSFEx model's samples give no finite shapelet fit (values out of range)");
    PsfField f;
    f.variation = m.variation;
    f.n_max = best_n;
    f.beta_pix = best.beta;
    f.max_residual_fraction = best.worst;
    f.reached_target = best.worst <= o.residual_target;
    for (int k = 0; k < kk; ++k) {
        CartesianModel c(0.0, 0.0, best.beta, best_n);
        int i = 0;
        for (int n1 = 0; n1 <= best_n; ++n1)
            for (int n2 = 0; n1 + n2 <= best_n; ++n2, ++i) c.b(n1, n2) = best.coeffs(i, k);
        f.flux.push_back(moments(c).flux);
        f.b.push_back(std::move(c.b));
    }
    return f;
}

CartesianModel PsfField::at(double x, double y) const {
    const std::vector<double> t = variation.terms(x, y);
    CartesianModel c(0.0, 0.0, beta_pix, n_max);
    double total = 0.0;
    for (std::size_t k = 0; k < t.size(); ++k) {
        c.b += t[k] * b[k];
        total += t[k] * flux[k];
    }
    if (!(total > 0))
        throw Error("the PSF field has no positive flux at (" + std::to_string(x) + ", " +
                    std::to_string(y) + "): its polynomial is taken far beyond its stars");
    c.b /= total;
    return c;
}

PsfField read_psf_field(const std::string& path, const PsfFieldOptions& options) {
    const PsfexModel m = read_psfex(path);
    try {
        return fit_psf_field(m, options);
    } catch (const Error& e) {
        throw Error(e.message(), path);
    }
}

}  // namespace shapesim
