#include "shapesim/lensing.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/text_rows.hpp"

#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <fstream>
#include <sstream>

namespace shapesim {

namespace {

using Cplx = std::complex<double>;

constexpr double arcsec_per_radian = 1.0 / arcsec;
constexpr double speed_of_light = 299792.458;        // km/s
constexpr double gravitational_constant = 4.30091727e-9;  // Mpc (km/s)² / M_sun (IAU 2015)

std::string number(double v) {
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
}

// The 2-D DFT of a row-major nx × ny array in place (forward: e^{−i…}, unscaled; inverse:
// e^{+i…} scaled by 1/(nx ny)), as 1-D transforms of the rows and then the columns.
void fft2(std::vector<Cplx>& a, long nx, long ny, bool inverse) {
    Eigen::FFT<double> fft;
    std::vector<Cplx> in, out;
    auto pass = [&]() {
        if (inverse) fft.inv(out, in);
        else fft.fwd(out, in);
    };
    in.resize(std::size_t(nx));
    for (long j = 0; j < ny; ++j) {
        std::copy_n(a.begin() + j * nx, nx, in.begin());
        pass();
        std::copy_n(out.begin(), nx, a.begin() + j * nx);
    }
    in.resize(std::size_t(ny));
    for (long i = 0; i < nx; ++i) {
        for (long j = 0; j < ny; ++j) in[std::size_t(j)] = a[std::size_t(j * nx + i)];
        pass();
        for (long j = 0; j < ny; ++j) a[std::size_t(j * nx + i)] = out[std::size_t(j)];
    }
}

// The signed frequency index of DFT bin k of n.
long signed_index(long k, long n) { return k <= n / 2 ? k : k - n; }

// Nodes per band-limit spacing: at 4 the Keys cubic keeps the power at the band's edge to
// ~2% halfway between nodes (at 2, 12%).
constexpr int oversampling = 4;

// The Keys cubic convolution kernel (a = −1/2): exact for quadratics, C¹.
double keys(double t) {
    t = std::abs(t);
    if (t < 1.0) return (1.5 * t - 2.5) * t * t + 1.0;
    if (t < 2.0) return ((-0.5 * t + 2.5) * t - 4.0) * t + 2.0;
    return 0.0;
}

}  // namespace

std::optional<Lensing> reduced(const Convergence& c, bool magnify,
                               const WeakLensingLimits& limits) {
    if (!(c.kappa < 1.0)) return std::nullopt;
    const double g1 = c.gamma1 / (1.0 - c.kappa), g2 = c.gamma2 / (1.0 - c.kappa);
    const double g_sq = g1 * g1 + g2 * g2;
    if (!(g_sq < 1.0) || !(std::sqrt(g_sq) <= limits.max_shear)) return std::nullopt;
    Lensing l;
    l.g1 = g1;
    l.g2 = g2;
    l.kappa = c.kappa;
    l.conserve_flux = !magnify;
    if (!(magnification(l) <= limits.max_magnification)) return std::nullopt;
    return l;
}

NfwProfile nfw_profile(double x, double kappa_s) {
    require(x > 0.0 && std::isfinite(x), "NFW profile: x = R/r_s must be finite and > 0");
    const double u = x * x - 1.0;
    double a, one_minus_a_over_u;  // A(x) and (1 − A)/(x² − 1)
    if (std::abs(u) < 0.1) {
        // A = Σ (−u)^k/(2k+1), (1 − A)/u = Σ (−u)^k/(2k+3): |u|^k < 1e-18 by k = 18.
        a = 0.0;
        one_minus_a_over_u = 0.0;
        double p = 1.0;
        for (int k = 0; k < 24; ++k, p *= -u) {
            a += p / double(2 * k + 1);
            one_minus_a_over_u += p / double(2 * k + 3);
        }
    } else if (x < 1.0) {
        const double s = std::sqrt(-u);
        a = std::log((1.0 + s) / x) / s;  // arccosh(1/x)/√(1−x²)
        one_minus_a_over_u = (1.0 - a) / u;
    } else {
        const double s = std::sqrt(u);
        a = std::atan(s) / s;  // arccos(1/x)/√(x²−1)
        one_minus_a_over_u = (1.0 - a) / u;
    }
    double h;  // A + ln(x/2)
    if (x < 0.5) {
        // ln(x/2) + A cancels as x → 0; with s = √(1−x²) and 1 − s = x²/(1+s) it is
        // [log1p(−x²/(2(1+s))) + x²/(1+s) (ln 2 − ln x)] / s, every term O(x²).
        const double s = std::sqrt(1.0 - x * x), t = x * x / (1.0 + s);
        h = (std::log1p(-0.5 * t) + t * (std::log(2.0) - std::log(x))) / s;
    } else {
        h = a + std::log(0.5 * x);
    }
    NfwProfile p;
    p.kappa = 2.0 * kappa_s * one_minus_a_over_u;
    p.gamma_t = 4.0 * kappa_s * h / (x * x) - p.kappa;
    return p;
}

void Cosmology::validate() const {
    if (!(h0 > 0.0 && h0 < 1000.0))
        throw Error("must be in (0, 1000) km/s/Mpc, got " + number(h0), "", 0, "h0");
    if (!(omega_m > 0.0 && omega_m <= 1.0))
        throw Error("must be in (0, 1], got " + number(omega_m), "", 0, "omega-m");
}

double Cosmology::hubble(double z) const {
    const double a = 1.0 + z;
    return h0 * std::sqrt(omega_m * a * a * a + (1.0 - omega_m));
}

double Cosmology::comoving_distance(double z) const {
    require(z >= 0.0 && z < 1100.0, "comoving distance: z must be in [0, 1100)");
    if (z == 0.0) return 0.0;
    const double integral = boost::math::quadrature::gauss_kronrod<double, 31>::integrate(
        [&](double zz) { return 1.0 / hubble(zz); }, 0.0, z, 15, 1e-14);
    return speed_of_light * integral;
}

double Cosmology::angular_diameter_distance(double z1, double z2) const {
    require(z2 > z1, "angular diameter distance: z2 must exceed z1");
    return (comoving_distance(z2) - comoving_distance(z1)) / (1.0 + z2);  // flat
}

double Cosmology::critical_density(double z) const {
    const double h = hubble(z);
    return 3.0 * h * h / (8.0 * pi * gravitational_constant);
}

double Cosmology::sigma_crit(double z_lens, double z_source) const {
    require(z_source > z_lens, "Σ_crit: the sources must lie behind the lens");
    const double dl = angular_diameter_distance(0.0, z_lens);
    const double ds = angular_diameter_distance(0.0, z_source);
    const double dls = angular_diameter_distance(z_lens, z_source);
    return speed_of_light * speed_of_light / (4.0 * pi * gravitational_constant) * ds / (dl * dls);
}

void NfwHalo::validate() const {
    if (!(std::isfinite(x) && std::isfinite(y)))
        throw Error("position must be finite", "", 0, "halo");
    if (!(mass > 0.0 && mass < 1e18))
        throw Error("M200 must be in (0, 1e18) M_sun, got " + number(mass), "", 0, "halo");
    if (!(concentration > 0.0 && concentration < 1000.0))
        throw Error("concentration must be in (0, 1000), got " + number(concentration), "", 0,
                    "halo");
    if (!(z > 0.0 && z < 20.0))
        throw Error("redshift must be in (0, 20), got " + number(z), "", 0, "halo");
}

NfwLens::NfwLens(const NfwHalo& halo, const Cosmology& cosmology, double z_source,
                 double pixel_scale)
    : halo_(halo), pixel_scale_(pixel_scale) {
    halo.validate();
    cosmology.validate();
    require(pixel_scale > 0.0, "NFW lens: pixel scale must be > 0");
    if (!(z_source > halo.z))
        throw Error("the sources (z = " + number(z_source) + ") must lie behind the halo (z = " +
                        number(halo.z) + ")",
                    "", 0, "source-z");
    const double rho_crit = cosmology.critical_density(halo.z);
    const double c = halo.concentration;
    const double r200 = std::cbrt(3.0 * halo.mass / (4.0 * pi * 200.0 * rho_crit));  // Mpc
    const double r_s = r200 / c;
    const double delta_c = 200.0 / 3.0 * c * c * c / (std::log1p(c) - c / (1.0 + c));
    kappa_s_ = delta_c * rho_crit * r_s / cosmology.sigma_crit(halo.z, z_source);
    r_s_arcsec_ = r_s / cosmology.angular_diameter_distance(0.0, halo.z) * arcsec_per_radian;
}

Convergence NfwLens::at(double x, double y) const {
    const double dx = (x - halo_.x) * pixel_scale_, dy = (y - halo_.y) * pixel_scale_;
    const double r = std::hypot(dx, dy);
    const NfwProfile p = nfw_profile(std::max(r / r_s_arcsec_, 1e-6), kappa_s_);
    Convergence c;
    c.kappa = p.kappa;
    if (r > 0.0) {
        // cos 2φ = (dx² − dy²)/r², sin 2φ = 2 dx dy / r².
        c.gamma1 = -p.gamma_t * (dx - dy) * (dx + dy) / (r * r);
        c.gamma2 = -p.gamma_t * 2.0 * dx * dy / (r * r);
    }
    return c;
}

PowerSpectrum::PowerSpectrum(std::vector<double> ell, std::vector<double> power)
    : ell_(std::move(ell)), power_(std::move(power)) {
    if (ell_.size() != power_.size() || ell_.size() < 2)
        throw Error("needs at least two rows of ell and P(ell)", "", 0, "power spectrum");
    for (std::size_t k = 0; k < ell_.size(); ++k) {
        if (!(ell_[k] > 0.0 && std::isfinite(ell_[k])) || (k > 0 && !(ell_[k] > ell_[k - 1])))
            throw Error("row " + std::to_string(k + 1) + ": ell must be finite, > 0 and increasing",
                        "", 0, "power spectrum");
        if (!(power_[k] >= 0.0 && std::isfinite(power_[k])))
            throw Error("row " + std::to_string(k + 1) + ": P(ell) must be finite and >= 0", "", 0,
                        "power spectrum");
    }
}

double PowerSpectrum::operator()(double ell) const {
    if (!(ell >= ell_.front() && ell <= ell_.back())) return 0.0;
    const std::size_t k =
        std::size_t(std::upper_bound(ell_.begin(), ell_.end(), ell) - ell_.begin());
    if (k == ell_.size()) return power_.back();
    const double l0 = ell_[k - 1], l1 = ell_[k], p0 = power_[k - 1], p1 = power_[k];
    const double t = std::log(ell / l0) / std::log(l1 / l0);
    if (p0 > 0.0 && p1 > 0.0) return p0 * std::pow(p1 / p0, t);
    return p0 + (p1 - p0) * t;
}

PowerSpectrum read_power_spectrum(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw Error("cannot open the power spectrum", path);
    std::vector<double> ell, power;
    for_each_text_row(in, path, [&](const std::string& text, long number_of_line) {
        std::istringstream fields(text);
        double l, p;
        std::string rest;
        if (!(fields >> l >> p) || (fields >> rest))
            throw Error("expected two numbers: ell P(ell)", path, number_of_line);
        if (!(l > 0.0 && std::isfinite(l)) || (!ell.empty() && !(l > ell.back())))
            throw Error("ell must be finite, > 0 and increasing", path, number_of_line);
        if (!(p >= 0.0 && std::isfinite(p)))
            throw Error("P(ell) must be finite and >= 0", path, number_of_line);
        ell.push_back(l);
        power.push_back(p);
    });
    if (ell.size() < 2) throw Error("needs at least two rows of ell and P(ell)", path);
    return PowerSpectrum(std::move(ell), std::move(power));
}

void GaussianFieldOptions::validate() const {
    if (!(spacing >= 0.0 && spacing < 1e7)) throw Error("must be >= 0 arcsec", "", 0, "spacing");
    if (!(padding >= 1.0 && padding <= 16.0)) throw Error("must be in [1, 16]", "", 0, "padding");
}

GaussianLensingField::GaussianLensingField(const PowerSpectrum& e,
                                           const std::optional<PowerSpectrum>& b,
                                           const FieldGeometry& field,
                                           const GaussianFieldOptions& options) {
    options.validate();
    require(field.nx > 0 && field.ny > 0 && field.pixel_scale > 0.0, "the field is empty");
    pixel_scale_ = field.pixel_scale;
    const double wx = double(field.nx) * field.pixel_scale,
                 wy = double(field.ny) * field.pixel_scale;
    const double spacing = options.spacing > 0.0 ? options.spacing : std::max(wx, wy) / 128.0;
    h_arcsec_ = spacing / double(oversampling);
    const double nodes_x = std::ceil(options.padding * wx / h_arcsec_);
    const double nodes_y = std::ceil(options.padding * wy / h_arcsec_);
    if (!(nodes_x * nodes_y <= double(options.max_nodes)))
        throw Error("a grid of " + number(nodes_x) + " x " + number(nodes_y) + " nodes (spacing " +
                        number(spacing) + "\" over " + number(options.padding) +
                        " x the field) is "
                        "more than " + std::to_string(options.max_nodes) +
                        ": give a larger spacing",
                    "", 0, "spacing");
    // Even node counts: the Nyquist row is then one row (it is outside the band anyway).
    mx_ = std::max(4L, long(nodes_x) + long(nodes_x) % 2);
    my_ = std::max(4L, long(nodes_y) + long(nodes_y) % 2);
    const double h = h_arcsec_ / arcsec_per_radian;
    ell_limit_ = pi / (spacing / arcsec_per_radian);
    const std::size_t n = std::size_t(mx_ * my_);

    auto white = [&](const char* purpose) {
        std::vector<Cplx> w(n);
        RandomStream stream(options.seed, 0, purpose);
        for (Cplx& v : w) v = stream.gaussian();
        fft2(w, mx_, my_, false);
        return w;
    };
    std::vector<Cplx> kappa_e = white("lensing field E");
    std::vector<Cplx> kappa_b;
    if (b) kappa_b = white("lensing field B");
    std::vector<Cplx> g1(n), g2(n);
    for (long j = 0; j < my_; ++j)
        for (long i = 0; i < mx_; ++i) {
            const std::size_t k = std::size_t(j * mx_ + i);
            const double lx = 2.0 * pi * double(signed_index(i, mx_)) / (double(mx_) * h);
            const double ly = 2.0 * pi * double(signed_index(j, my_)) / (double(my_) * h);
            const double l2 = lx * lx + ly * ly, l = std::sqrt(l2);
            if (l2 == 0.0 || !(l < ell_limit_)) {
                kappa_e[k] = 0.0;
                if (b) kappa_b[k] = 0.0;
                continue;
            }
            // κ̃ = W h √P, and κ = (1/(h² M M')) Σ κ̃ e^{iℓθ}: the inverse DFT of W √P / h.
            kappa_e[k] *= std::sqrt(e(l)) / h;
            const double c2 = (lx * lx - ly * ly) / l2, s2 = 2.0 * lx * ly / l2;
            g1[k] = c2 * kappa_e[k];
            g2[k] = s2 * kappa_e[k];
            if (b) {
                kappa_b[k] *= std::sqrt((*b)(l)) / h;
                g1[k] -= s2 * kappa_b[k];
                g2[k] += c2 * kappa_b[k];
            }
        }
    kappa_b.clear();
    kappa_b.shrink_to_fit();
    fft2(kappa_e, mx_, my_, true);
    fft2(g1, mx_, my_, true);
    fft2(g2, mx_, my_, true);
    kappa_.resize(n);
    gamma1_.resize(n);
    gamma2_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        kappa_[k] = kappa_e[k].real();
        gamma1_[k] = g1[k].real();
        gamma2_[k] = g2[k].real();
    }
}

Convergence GaussianLensingField::node(long i, long j) const {
    require(i >= 0 && i < mx_ && j >= 0 && j < my_, "lensing field: node outside the grid");
    const std::size_t k = std::size_t(j * mx_ + i);
    return Convergence{kappa_[k], gamma1_[k], gamma2_[k]};
}

Convergence GaussianLensingField::at(double x, double y) const {
    require(std::isfinite(x) && std::isfinite(y) && std::abs(x) < 1e12 && std::abs(y) < 1e12,
            "lensing field: position must be finite");
    const double u = (x - 0.5) * pixel_scale_ / h_arcsec_, v = (y - 0.5) * pixel_scale_ / h_arcsec_;
    const double fu = std::floor(u), fv = std::floor(v);
    const double tu = u - fu, tv = v - fv;
    auto wrap = [](long k, long n) { return ((k % n) + n) % n; };
    const long i0 = wrap(long(fu), mx_), j0 = wrap(long(fv), my_);
    double wu[4], wv[4];
    for (int a = 0; a < 4; ++a) {
        wu[a] = keys(tu - double(a - 1));
        wv[a] = keys(tv - double(a - 1));
    }
    Convergence c;
    for (int bj = 0; bj < 4; ++bj) {
        const long j = wrap(j0 + bj - 1, my_);
        Convergence row;
        for (int ai = 0; ai < 4; ++ai) {
            const std::size_t k = std::size_t(j * mx_ + wrap(i0 + ai - 1, mx_));
            row.kappa += wu[ai] * kappa_[k];
            row.gamma1 += wu[ai] * gamma1_[k];
            row.gamma2 += wu[ai] * gamma2_[k];
        }
        c.kappa += wv[bj] * row.kappa;
        c.gamma1 += wv[bj] * row.gamma1;
        c.gamma2 += wv[bj] * row.gamma2;
    }
    return c;
}

Convergence LensingSources::at(double x, double y) const {
    Convergence c = constant;
    for (const NfwLens& halo : halos) c += halo.at(x, y);
    if (gaussian) c += gaussian->at(x, y);
    return c;
}

BinnedPower shear_power(const std::vector<double>& gamma1, const std::vector<double>& gamma2,
                        long nx, long ny, double spacing_rad, const std::vector<double>& edges) {
    require(
        nx > 0 && ny > 0 && gamma1.size() == std::size_t(nx * ny) && gamma2.size() == gamma1.size(),
        "shear_power: the arrays must hold nx × ny values");
    require(edges.size() >= 2 && spacing_rad > 0.0, "shear_power: needs bin edges and a spacing");
    std::vector<Cplx> a(gamma1.begin(), gamma1.end()), c(gamma2.begin(), gamma2.end());
    fft2(a, nx, ny, false);
    fft2(c, nx, ny, false);
    const std::size_t bins = edges.size() - 1;
    BinnedPower out;
    out.ell.assign(bins, 0.0);
    out.e.assign(bins, 0.0);
    out.b.assign(bins, 0.0);
    out.modes.assign(bins, 0);
    const double area = double(nx) * spacing_rad * double(ny) * spacing_rad;
    const double h2 = spacing_rad * spacing_rad;
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i) {
            const double lx = 2.0 * pi * double(signed_index(i, nx)) / (double(nx) * spacing_rad);
            const double ly = 2.0 * pi * double(signed_index(j, ny)) / (double(ny) * spacing_rad);
            const double l2 = lx * lx + ly * ly, l = std::sqrt(l2);
            if (l2 == 0.0) continue;
            const auto at = std::upper_bound(edges.begin(), edges.end(), l);
            if (at == edges.begin() || at == edges.end()) continue;
            const std::size_t bin = std::size_t(at - edges.begin()) - 1;
            const double c2 = (lx * lx - ly * ly) / l2, s2 = 2.0 * lx * ly / l2;
            const std::size_t k = std::size_t(j * nx + i);
            const Cplx ke = h2 * (c2 * a[k] + s2 * c[k]), kb = h2 * (-s2 * a[k] + c2 * c[k]);
            out.ell[bin] += l;
            out.e[bin] += std::norm(ke) / area;
            out.b[bin] += std::norm(kb) / area;
            ++out.modes[bin];
        }
    for (std::size_t k = 0; k < bins; ++k) {
        const double n = double(out.modes[k]);
        out.ell[k] = n > 0 ? out.ell[k] / n : std::nan("");
        out.e[k] = n > 0 ? out.e[k] / n : std::nan("");
        out.b[k] = n > 0 ? out.b[k] / n : std::nan("");
    }
    return out;
}

}  // namespace shapesim
