// Shapelet models: the packed polar coefficient order and the two model types.
//
// A model is f(x) = Σ_{n,m} a_{n,m} χ_{n,m}(x − x_c; β) (paper eq. 1), n − |m| even.
// Images are real, so a_{n,−m} = conj a_{n,m} and only m ≥ 0 is stored, packed as
//   n = 0..n_max, and within each n, m = n mod 2, n mod 2 + 2, …, n      (DESIGN §2)
// e.g. n_max 2: (0,0) (1,1) (2,0) (2,2). Every a_{n,0} is real.
//
// Units (DESIGN §2): everything here is in pixels. The centre (x, y) is in FITS pixel
// coordinates (first pixel centred at (1, 1)); β is `beta_pix`. The coefficients describe the
// image in its own units per pixel, so flux = 2√π β_pix Σ_{n even} a_{n,0}. Records convert
// from arcsec (beta / pixel_scale) explicitly, never implicitly.
//
// The "real parameter vector" of a model (used by fits, covariances and the smoothing space)
// walks the packed order and takes Re a_{n,0} for m = 0, and Re a_{n,m}, Im a_{n,m} for m > 0:
// (n_max+1)(n_max+2)/2 numbers, the same count as Cartesian coefficients.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <vector>

namespace shapesim {

using Complex = std::complex<double>;

/// Number of stored polar coefficients (m ≥ 0) up to n_max.
constexpr int polar_count(int n_max) {
    return n_max < 0 ? 0 : ((n_max + 2) / 2) * ((n_max + 3) / 2);
}

/// Index of (n, m), m ≥ 0 and n − m even, in the packed order.
constexpr int polar_index(int n, int m) {
    return (n % 2 == 0 ? (n / 2) * (n / 2 + 1) : ((n + 1) / 2) * ((n + 1) / 2)) + (m - n % 2) / 2;
}

/// Number of real parameters (= Cartesian coefficients) up to n_max.
constexpr int real_count(int n_max) { return n_max < 0 ? 0 : (n_max + 1) * (n_max + 2) / 2; }

struct PolarIndex {
    int n, m;
};
/// The packed (n, m ≥ 0) sequence up to n_max.
std::vector<PolarIndex> polar_indices(int n_max);

/// A polar shapelet model (galaxy or PSF), in pixel units.
struct ShapeletModel {
    double x = 0.0, y = 0.0;      ///< centre, FITS pixel coordinates
    double beta_pix = 1.0;        ///< scale β in pixels
    int n_max = 0;
    std::vector<Complex> coeffs;  ///< packed a_{n,m}, m ≥ 0; size polar_count(n_max)

    ShapeletModel() = default;
    ShapeletModel(double x_, double y_, double beta_pix_, int n_max_)
        : x(x_), y(y_), beta_pix(beta_pix_), n_max(n_max_), coeffs(polar_count(n_max_)) {}

    Complex& at(int n, int m) { return coeffs[polar_index(n, m)]; }
    Complex at(int n, int m) const { return coeffs[polar_index(n, m)]; }
    /// Throws Error unless sizes agree, β > 0 and finite, every a_{n,0} real, all finite.
    void validate() const;
};

/// A Cartesian shapelet model: f(x, y) = Σ b(n1, n2) B_{n1}(x − x_c) B_{n2}(y − y_c), with
/// n1 along x (image columns), n2 along y (rows); b is (n_max+1)², zero where n1 + n2 > n_max.
struct CartesianModel {
    double x = 0.0, y = 0.0;
    double beta_pix = 1.0;
    int n_max = 0;
    Eigen::MatrixXd b;

    CartesianModel() = default;
    CartesianModel(double x_, double y_, double beta_pix_, int n_max_)
        : x(x_), y(y_), beta_pix(beta_pix_), n_max(n_max_),
          b(Eigen::MatrixXd::Zero(n_max_ + 1, n_max_ + 1)) {}
};

/// The real parameter vector of a polar model (order in the file comment).
Eigen::VectorXd real_parameters(const ShapeletModel& model);
/// Set a model's coefficients from a real parameter vector of size real_count(n_max).
void set_real_parameters(ShapeletModel& model, const Eigen::VectorXd& params);

/// The model truncated or zero-padded to another n_max (same centre and β).
ShapeletModel with_n_max(const ShapeletModel& model, int n_max);

}  // namespace shapesim
