// Lensing fields: the convergence κ and shear γ each galaxy sees, from NFW halos (closed form,
// Wright & Brainerd 2000) and from Gaussian random fields of a convergence power spectrum;
// summed, then reduced to the g = γ/(1−κ) and κ that render applies in shapelet space
// (transform.hpp lens). Frame: field pixels, x right, y up (FITS), angles counter-clockwise
// from +x: γ1 > 0 stretches along x, γ2 > 0 along x = y (sky-frame γ2 on a north-up,
// east-left image has the opposite sign).
// Derivation: docs/algorithms.md#lensing-fields
#pragma once

#include "shapesim/geometry.hpp"
#include "shapesim/transform.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// Convergence and (unreduced) shear at a point; lenses add.
struct Convergence {
    double kappa = 0.0, gamma1 = 0.0, gamma2 = 0.0;
    Convergence& operator+=(const Convergence& o) {
        kappa += o.kappa;
        gamma1 += o.gamma1;
        gamma2 += o.gamma2;
        return *this;
    }
};

/// Where a galaxy's lensing is still the local, weak kind this code draws: the lens applied as
/// one matrix over the galaxy holds while |g| and μ stay moderate; near a critical curve
/// (|g| → 1, μ → ∞) it stretches a galaxy into a straight bar across the field, not an arc.
struct WeakLensingLimits {
    double max_shear = 0.5;           ///< |g| at most this
    double max_magnification = 10.0;  ///< μ at most this
};

/// The reduced shear g = γ/(1−κ) and κ; nullopt where the weak-lensing description fails:
/// κ ≥ 1, |g| beyond `limits.max_shear` (< 1: multiple images are not modelled) or μ beyond
/// `limits.max_magnification`.
std::optional<Lensing> reduced(const Convergence& c, bool magnify = true,
                               const WeakLensingLimits& limits = {});

/// κ and γ_t of an NFW halo at x = R/r_s > 0 for κ_s = ρ_s r_s / Σ_crit (Wright & Brainerd).
struct NfwProfile {
    double kappa = 0.0, gamma_t = 0.0;
};
NfwProfile nfw_profile(double x, double kappa_s);

/// Flat ΛCDM (Ω_Λ = 1 − Ω_m, radiation neglected): distances in Mpc, densities in M_sun/Mpc³.
struct Cosmology {
    double h0 = 70.0;      ///< km/s/Mpc
    double omega_m = 0.3;
    void validate() const;
    double hubble(double z) const;                ///< H(z), km/s/Mpc
    double comoving_distance(double z) const;     ///< line-of-sight comoving distance, Mpc
    double angular_diameter_distance(double z1, double z2) const;  ///< from z1 to z2 > z1
    double critical_density(double z) const;      ///< 3H²/(8πG), M_sun/Mpc³
    double sigma_crit(double z_lens, double z_source) const;  ///< c²D_s/(4πG D_l D_ls), M_sun/Mpc²
};

/// One halo: where, how massive, how concentrated, how far.
struct NfwHalo {
    double x = 0.0, y = 0.0;      ///< centre, field FITS pixels
    double mass = 0.0;            ///< M200 (critical), M_sun
    double concentration = 0.0;   ///< r200 / r_s
    double z = 0.0;               ///< lens redshift
    /// Error unless mass > 0, concentration > 0 and z > 0 are finite.
    void validate() const;
};

/// An NFW halo's lensing of sources at one redshift, in a field of `pixel_scale` arcsec/pixel.
class NfwLens {
public:
    NfwLens(const NfwHalo& halo, const Cosmology& cosmology, double z_source, double pixel_scale);
    /// κ and γ at field pixel (x, y); at the centre itself γ = 0 and κ its limit is infinite,
    /// so a point within 1e-6 r_s of it is evaluated at that radius.
    Convergence at(double x, double y) const;
    double r_s_arcsec() const { return r_s_arcsec_; }
    double kappa_s() const { return kappa_s_; }

private:
    NfwHalo halo_;
    double pixel_scale_, r_s_arcsec_ = 0.0, kappa_s_ = 0.0;
};

/// A tabulated power spectrum P(ℓ) (ℓ in 1/radian, P in steradian), interpolated linearly in
/// log ℓ – log P (linearly in P next to a zero), zero outside the table.
class PowerSpectrum {
public:
    /// Error unless ℓ > 0 strictly increasing, P ≥ 0, all finite, at least two rows.
    PowerSpectrum(std::vector<double> ell, std::vector<double> power);
    double operator()(double ell) const;
    double ell_min() const { return ell_.front(); }
    double ell_max() const { return ell_.back(); }

private:
    std::vector<double> ell_, power_;
};

/// A two-column text table "ℓ P(ℓ)" ('#' starts a comment); Error naming the file and line.
PowerSpectrum read_power_spectrum(const std::string& path);

struct GaussianFieldOptions {
    /// arcsec: the field holds |ℓ| < π/spacing (0: the field's longer side / 128)
    double spacing = 0.0;
    double padding = 2.0;  ///< the grid's period over the field's size, each axis (≥ 1)
    std::uint64_t seed = 0;
    long max_nodes = 2048L * 2048L;  ///< refused beyond (memory: 24 bytes a node, 72 while made)
    void validate() const;
};

/// A Gaussian random lensing field realised over a field (docs/algorithms.md#lensing-fields).
class GaussianLensingField {
public:
    /// E mode from `e`, B mode from `b` when given.
    GaussianLensingField(const PowerSpectrum& e, const std::optional<PowerSpectrum>& b,
                         const FieldGeometry& field, const GaussianFieldOptions& options);
    /// κ, γ at field pixel (x, y) (Keys cubic between nodes; the grid is periodic).
    Convergence at(double x, double y) const;
    /// κ, γ at grid node (i, j), 0 ≤ i < nodes_x, 0 ≤ j < nodes_y (node (0, 0) is pixel
    /// (0.5, 0.5), the field's lower-left corner; nodes are node_spacing arcsec apart).
    Convergence node(long i, long j) const;
    long nodes_x() const { return mx_; }
    long nodes_y() const { return my_; }
    double node_spacing() const { return h_arcsec_; }  ///< arcsec (spacing / 4)
    double ell_limit() const { return ell_limit_; }      ///< π / spacing, 1/radian

private:
    long mx_ = 0, my_ = 0;
    double h_arcsec_ = 0.0, ell_limit_ = 0.0, pixel_scale_ = 0.0;
    std::vector<double> kappa_, gamma1_, gamma2_;  ///< row-major, j * mx_ + i
};

/// Every lens of a scene: a constant κ and γ, NFW halos and a Gaussian random field, summed.
struct LensingSources {
    Convergence constant;
    std::vector<NfwLens> halos;
    std::optional<GaussianLensingField> gaussian;
    /// The summed κ and γ at field pixel (x, y).
    Convergence at(double x, double y) const;
};

/// The E- and B-mode power of γ on a periodic grid of nx × ny nodes spaced `spacing_rad`,
/// (row-major), in bins of ℓ: edges[k] ≤ |ℓ| < edges[k+1]; the estimator κ̃_E = h² DFT of
/// (cos 2φ γ1 + sin 2φ γ2), P = |κ̃|²/(L L'), averaged over the modes of each bin (a bin with no
/// mode gets NaN). The test's and the lensing page's measure of a realised field.
struct BinnedPower {
    std::vector<double> ell, e, b;  ///< mean |ℓ| of the bin's modes, E power, B power
    std::vector<long> modes;
};
BinnedPower shear_power(const std::vector<double>& gamma1, const std::vector<double>& gamma2,
                        long nx, long ny, double spacing_rad, const std::vector<double>& edges);

}  // namespace shapesim
