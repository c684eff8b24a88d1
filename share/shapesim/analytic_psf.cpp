#include "shapesim/analytic_psf.hpp"

#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

namespace shapesim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFwhmPerSigma = 2.3548200450309493;  // 2√(2 ln 2)
constexpr int kOversample = 5;

double moffat_alpha(const AnalyticPsf& p) {
    return p.fwhm / (2.0 * std::sqrt(std::pow(2.0, 1.0 / p.beta) - 1.0));
}

// 2J₁(u)/u, 1 at u = 0.
double jinc(double u) { return u < 1e-8 ? 1.0 : 2.0 * std::cyl_bessel_j(1.0, u) / u; }

// ∫ profile 2πr dr over the plane (arcsec²): closed forms, numerically for Airy (Simpson on
// u = πr/(λ/D) to 200 λ/D, where the unobscured Airy's missing light is 2/(π u) ≈ 0.1%).
double total_flux(const AnalyticPsf& p) {
    switch (p.kind) {
    case AnalyticPsf::Kind::gaussian: {
        const double s = p.fwhm / kFwhmPerSigma;
        return 2.0 * kPi * s * s;
    }
    case AnalyticPsf::Kind::moffat: {
        const double a = moffat_alpha(p);
        return kPi * a * a / (p.beta - 1.0);
    }
    case AnalyticPsf::Kind::airy: {
        const double scale = p.lambda_over_d / kPi;  // r = scale · u
        const int n = 200000;
        const double top = 200.0 * kPi, h = top / n;
        double sum = 0.0;
        for (int k = 0; k <= n; ++k) {
            const double u = k * h;
            const double f = p.profile(scale * u) * u;
            sum += f * (k == 0 || k == n ? 1.0 : (k % 2 ? 4.0 : 2.0));
        }
        return 2.0 * kPi * scale * scale * sum * h / 3.0;
    }
    }
    return 1.0;
}

// Separable Gaussian blur of σ pixels (kernel to ±4σ, normalised; light leaving the image is
// lost, as it leaves the stamp).
ImageArray gaussian_blur(const ImageArray& in, double sigma) {
    if (!(sigma > 0.0)) return in;
    const int half = int(std::ceil(4.0 * sigma));
    std::vector<double> kernel(std::size_t(2 * half + 1));
    double sum = 0.0;
    for (int k = -half; k <= half; ++k)
        sum += kernel[std::size_t(k + half)] = std::exp(-0.5 * k * k / (sigma * sigma));
    for (double& v : kernel) v /= sum;
    const Eigen::Index ny = in.rows(), nx = in.cols();
    ImageArray rows = ImageArray::Zero(ny, nx), out = ImageArray::Zero(ny, nx);
    for (Eigen::Index y = 0; y < ny; ++y)
        for (Eigen::Index x = 0; x < nx; ++x)
            for (int k = -half; k <= half; ++k)
                if (x + k >= 0 && x + k < nx)
                    rows(y, x) += kernel[std::size_t(k + half)] * in(y, x + k);
    for (Eigen::Index y = 0; y < ny; ++y)
        for (int k = -half; k <= half; ++k)
            if (y + k >= 0 && y + k < ny)
                out.row(y) += kernel[std::size_t(k + half)] * rows.row(y + k);
    return out;
}

// Bilinear value of `image` (pixels of `scale`, centred on its middle pixel) at (x, y) arcsec.
double bilinear(const ImageArray& image, double scale, double x, double y) {
    const double c = 0.5 * double(image.cols() - 1);
    const double fx = x / scale + c, fy = y / scale + c;
    const Eigen::Index i = Eigen::Index(std::floor(fx)), j = Eigen::Index(std::floor(fy));
    if (i < 0 || j < 0 || i + 1 >= image.cols() || j + 1 >= image.rows()) return 0.0;
    const double ax = fx - double(i), ay = fy - double(j);
    return (1 - ax) * (1 - ay) * image(j, i) + ax * (1 - ay) * image(j, i + 1) +
           (1 - ax) * ay * image(j + 1, i) + ax * ay * image(j + 1, i + 1);
}

// FWHM (arcsec) of the azimuthal mean of `image` about its middle: where the mean over 64
// angles falls to half its value at the centre (bisection to 1e-6 of the search range).
double radial_fwhm(const ImageArray& image, double scale) {
    const auto ring = [&](double r) {
        double s = 0.0;
        for (int k = 0; k < 64; ++k) {
            const double t = 2.0 * kPi * (k + 0.5) / 64.0;
            s += bilinear(image, scale, r * std::cos(t), r * std::sin(t));
        }
        return s / 64.0;
    };
    const double half = 0.5 * ring(0.0);
    double lo = 0.0, hi = scale;
    const double edge = 0.5 * scale * double(image.cols() - 1);
    while (ring(hi) > half && hi < edge) hi *= 1.5;
    hi = std::min(hi, edge);
    for (int it = 0; it < 60 && hi - lo > 1e-6 * edge; ++it) {
        const double mid = 0.5 * (lo + hi);
        (ring(mid) > half ? lo : hi) = mid;
    }
    return 2.0 * 0.5 * (lo + hi);
}

// Light of `image` (pixels of `scale`, centred on its middle) within radius r (pixel centres).
double encircled(const ImageArray& image, double scale, double r) {
    const double c = 0.5 * double(image.cols() - 1);
    double s = 0.0;
    for (Eigen::Index y = 0; y < image.rows(); ++y)
        for (Eigen::Index x = 0; x < image.cols(); ++x)
            if (std::hypot((double(x) - c) * scale, (double(y) - c) * scale) <= r) s += image(y, x);
    return s;
}

}  // namespace

double AnalyticPsf::profile(double r) const {
    switch (kind) {
    case Kind::gaussian: {
        const double s = fwhm / kFwhmPerSigma;
        return std::exp(-0.5 * r * r / (s * s));
    }
    case Kind::moffat: {
        const double a = moffat_alpha(*this);
        return std::pow(1.0 + r * r / (a * a), -beta);
    }
    case Kind::airy: {
        const double u = kPi * r / lambda_over_d, e = obscuration;
        const double amplitude = (jinc(u) - e * e * jinc(e * u)) / (1.0 - e * e);
        return amplitude * amplitude;
    }
    }
    return 0.0;
}

double AnalyticPsf::nominal_fwhm() const {
    if (kind != Kind::airy) return fwhm;
    double lo = 0.0, hi = 1.22 * lambda_over_d;  // the first dark ring bounds the half maximum
    for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (profile(mid) > 0.5 ? lo : hi) = mid;
    }
    return lo + hi;
}

std::string AnalyticPsf::describe() const {
    std::ostringstream s;
    s.precision(10);
    switch (kind) {
    case Kind::gaussian: s << "gaussian:" << fwhm; break;
    case Kind::moffat: s << "moffat:" << fwhm << "," << beta; break;
    case Kind::airy: s << "airy:" << lambda_over_d << "," << obscuration; break;
    }
    if (jitter > 0.0) s << ";jitter=" << jitter;
    return s.str();
}

void AnalyticPsf::validate() const {
    const auto fail = [&](const std::string& what) {
        throw Error(describe() + ": " + what, "", 0, "psf");
    };
    if (kind != Kind::airy && !(fwhm > 0.0 && fwhm < 3600.0)) fail("the FWHM must be > 0 arcsec");
    if (kind == Kind::moffat && !(beta > 1.0 && beta < 1000.0)) fail("Moffat's beta must be > 1");
    if (kind == Kind::airy && !(lambda_over_d > 0.0 && lambda_over_d < 3600.0))
        fail("lambda/D must be > 0 arcsec");
    if (kind == Kind::airy && !(obscuration >= 0.0 && obscuration < 1.0))
        fail("the obscuration must be in [0, 1)");
    if (!(jitter >= 0.0 && jitter < 3600.0)) fail("the jitter must be ≥ 0 arcsec");
}

AnalyticPsf parse_analytic_psf(const std::string& spec) {
    const auto bad = [&]() {
        return Error("'" + spec + "' is not an analytic PSF: gaussian:FWHM, moffat:FWHM[,BETA] "
                     "or airy:LAMBDA_OVER_D[,OBSCURATION], optionally ;jitter=SIGMA (arcsec)",
                     "", 0, "psf");
    };
    std::string main = spec, rest;
    if (const auto semi = spec.find(';'); semi != std::string::npos) {
        main = spec.substr(0, semi);
        rest = spec.substr(semi + 1);
    }
    const auto colon = main.find(':');
    if (colon == std::string::npos) throw bad();
    const std::string kind = main.substr(0, colon);
    std::vector<double> numbers;
    std::stringstream list(main.substr(colon + 1));
    std::string item;
    while (std::getline(list, item, ',')) {
        try {
            std::size_t used = 0;
            numbers.push_back(std::stod(item, &used));
            if (used != item.size()) throw bad();
        } catch (const std::logic_error&) {
            throw bad();
        }
    }
    AnalyticPsf p;
    if (kind == "gaussian" && numbers.size() == 1) {
        p.kind = AnalyticPsf::Kind::gaussian;
        p.fwhm = numbers[0];
    } else if (kind == "moffat" && (numbers.size() == 1 || numbers.size() == 2)) {
        p.kind = AnalyticPsf::Kind::moffat;
        p.fwhm = numbers[0];
        if (numbers.size() == 2) p.beta = numbers[1];
    } else if (kind == "airy" && (numbers.size() == 1 || numbers.size() == 2)) {
        p.kind = AnalyticPsf::Kind::airy;
        p.lambda_over_d = numbers[0];
        if (numbers.size() == 2) p.obscuration = numbers[1];
    } else {
        throw bad();
    }
    if (!rest.empty()) {
        if (rest.rfind("jitter=", 0) != 0) throw bad();
        try {
            std::size_t used = 0;
            p.jitter = std::stod(rest.substr(7), &used);
            if (used != rest.size() - 7) throw bad();
        } catch (const std::logic_error&) {
            throw bad();
        }
    }
    p.validate();
    return p;
}

ImageArray analytic_psf_image(const AnalyticPsf& psf, double scale, int side) {
    psf.validate();
    require(side >= 3 && side % 2 == 1 && scale > 0.0, "the PSF image needs an odd side ≥ 3");
    const double c = 0.5 * double(side - 1), norm = scale * scale / total_flux(psf);
    ImageArray image(side, side);
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            double s = 0.0;
            for (int b = -1; b <= 1; ++b)
                for (int a = -1; a <= 1; ++a)
                    s += psf.profile(
                        std::hypot((x - c + a / 3.0) * scale, (y - c + b / 3.0) * scale));
            image(y, x) = s / 9.0 * norm;
        }
    return gaussian_blur(image, psf.jitter / scale);
}

PsfFitOptions analytic_psf_fit() {
    PsfFitOptions o;
    o.residual_target = 0.002;
    o.n_max_cap = 30;
    return o;
}

namespace {

// One model of the fine image at `options`, and its errors against the profile.
void model_and_measure(const ImageArray& fine, double target_scale, const PsfFitOptions& options,
                       AnalyticPsfModel& out) {
    out.psf = psf_from_oversampled(fine, out.fine_scale, target_scale, {}, out.stamp, options);
    // The model on the same fine grid (unit flux), near the core only: FWHM and the light
    // within 2 FWHM.
    const int half = std::min(out.stamp * kOversample / 2,
                              int(std::ceil(2.5 * out.fwhm / out.fine_scale)) + 2);
    const int c = out.stamp * kOversample / 2;
    const ImageArray core = fine.block(c - half, c - half, 2 * half + 1, 2 * half + 1);
    ImageArray model(2 * half + 1, 2 * half + 1);
    const double centre = 0.5 * (out.stamp + 1);  // the stamp's middle, FITS pixels
    const double area = std::pow(1.0 / kOversample, 2);
    for (int y = -half; y <= half; ++y)
        for (int x = -half; x <= half; ++x)
            model(y + half, x + half) =
                evaluate(out.psf.model, centre + double(x) / kOversample,
                         centre + double(y) / kOversample) * area;
    out.fwhm_error = radial_fwhm(model, out.fine_scale) / out.fwhm - 1.0;
    // The model holds the stamp's light (flux_outside is reported apart): compared as such.
    const double held = 1.0 - out.flux_outside;
    out.ee_error_1 = held * encircled(model, out.fine_scale, out.fwhm) -
                     encircled(core, out.fine_scale, out.fwhm);
    out.ee_error_2 = held * encircled(model, out.fine_scale, 2.0 * out.fwhm) -
                     encircled(core, out.fine_scale, 2.0 * out.fwhm);
}

}  // namespace

double AnalyticPsfModel::worst_error() const {
    return std::max({std::abs(fwhm_error), std::abs(ee_error_1), std::abs(ee_error_2)});
}

AnalyticPsfModel analytic_psf_model(const AnalyticPsf& psf, double target_scale,
                                    const PsfFitOptions& options, double tolerance) {
    psf.validate();
    require(target_scale > 0.0, "the pixel scale must be > 0");
    double reach = 0.0;
    switch (psf.kind) {
    case AnalyticPsf::Kind::gaussian: reach = 4.0 * psf.fwhm; break;
    case AnalyticPsf::Kind::moffat: reach = 8.0 * psf.fwhm; break;
    case AnalyticPsf::Kind::airy: reach = 12.0 * psf.lambda_over_d; break;
    }
    reach += 4.0 * psf.jitter;
    AnalyticPsfModel out;
    out.stamp = std::clamp(2 * int(std::ceil(reach / target_scale)) + 1, 21, 201);
    out.fine_scale = target_scale / kOversample;
    const ImageArray fine = analytic_psf_image(psf, out.fine_scale, out.stamp * kOversample);
    out.flux_outside = 1.0 - fine.sum();
    out.fwhm = radial_fwhm(fine, out.fine_scale);
    // The residual target halved until the FWHM and encircled energies are within tolerance
    // (or the order cap or a 1e-4 target is reached).
    PsfFitOptions fit = options;
    model_and_measure(fine, target_scale, fit, out);
    out.residual_target = fit.residual_target;
    for (int halving = 0; halving < 4 && out.worst_error() > tolerance &&
                          fit.residual_target > 1e-4 && out.psf.n_max < fit.n_max_cap;
         ++halving) {
        fit.residual_target *= 0.5;
        AnalyticPsfModel next = out;
        model_and_measure(fine, target_scale, fit, next);
        if (!(next.worst_error() < out.worst_error())) break;  // no better: the basis' limit
        out = next;
        out.residual_target = fit.residual_target;
    }
    out.psf.model.x = out.psf.model.y = 0.0;
    return out;
}

}  // namespace shapesim
