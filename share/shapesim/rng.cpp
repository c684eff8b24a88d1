#include "shapesim/rng.hpp"

#include "shapesim/error.hpp"

#include <Random123/philox.h>

#include <cmath>
#include <string>

namespace shapesim {

std::array<std::uint64_t, 4> philox_block(const std::array<std::uint64_t, 4>& counter,
                                          const std::array<std::uint64_t, 2>& key) {
    const r123::Philox4x64::ctr_type c = {{counter[0], counter[1], counter[2], counter[3]}};
    const r123::Philox4x64::key_type k = {{key[0], key[1]}};
    const r123::Philox4x64::ctr_type r = r123::Philox4x64()(c, k);
    return {r[0], r[1], r[2], r[3]};
}

RandomStream::RandomStream(std::uint64_t seed, std::uint64_t object_id, std::string_view purpose)
    : key_{seed, object_id}, purpose_(fnv1a_64(purpose)) {}

RandomStream::RandomStream(std::uint64_t seed, std::string_view object_id,
                           std::string_view purpose)
    : RandomStream(seed, fnv1a_64(object_id), purpose) {}

void RandomStream::first_blocks(std::uint64_t seed, const std::uint64_t* ids, std::size_t n,
                                PurposeHash purpose, std::array<std::uint64_t, 4>* out) {
    for (std::size_t i = 0; i < n; ++i)
        out[i] = philox_block({0, purpose.value, 0, 0}, {seed, ids[i]});
}

void RandomStream::refill() {
    buffered_block_ = position_ >> 2;
    buffer_ = philox_block({buffered_block_, purpose_, 0, 0}, key_);
}

std::uint64_t RandomStream::uniform_index(std::uint64_t n) {
    require(n >= 1, "uniform_index: n must be >= 1");
    // Words below 2⁶⁴ mod n would make the low residues more likely: reject them.
    const std::uint64_t threshold = (0 - n) % n;
    std::uint64_t word;
    do word = next_u64();
    while (word < threshold);
    return word % n;
}

std::pair<double, double> RandomStream::gaussian_pair() {
    const double u1 = uniform_open();  // (0, 1): the log is finite
    const double u2 = uniform();
    const double radius = std::sqrt(-2.0 * std::log(u1));
    const double theta = 6.283185307179586477 * u2;
    return {radius * std::cos(theta), radius * std::sin(theta)};
}

double RandomStream::epanechnikov() {
    // Uniforms on [−1, 1): 2u − 1 is exact for u = k·2⁻⁵³.
    const double first = 2.0 * uniform() - 1.0;
    const double second = 2.0 * uniform() - 1.0;
    const double third = 2.0 * uniform() - 1.0;
    const bool first_is_highest =
        std::abs(first) >= std::abs(second) && std::abs(first) >= std::abs(third);
    return first_is_highest ? second : first;
}

namespace detail {

const double* small_log_factorials() {
    static const auto table = [] {
        std::array<double, 21> t{};
        double product = 1.0;
        for (int k = 0; k <= 20; ++k) {
            if (k > 1) product *= k;
            t[std::size_t(k)] = lane::log(product);
        }
        return t;
    }();
    return table.data();
}

// Inversion: walk the CDF from 0 with one uniform (μ < 10, so e^{−μ} > 4.5e-5).
std::uint64_t poisson_inversion(double mean, double u) {
    double p = lane::exp(-mean), cdf = p;
    std::uint64_t k = 0;
    while (u > cdf) {
        ++k;
        p *= k < 64 ? mean * reciprocals.value[k] : mean / double(k);
        if (p < 1e-300) break;  // u beyond the rounded total: the far tail, probability ~1e-16
        cdf += p;
    }
    return k;
}

void check_poisson_mean(double mean) {
    if (!(mean >= 0.0) || !(mean <= 0x1.0p62))
        throw Error("poisson: mean must be finite, >= 0 and <= 2^62, got " +
                    std::to_string(mean));
}

}  // namespace detail

std::uint64_t RandomStream::poisson(double mean) { return poisson_deviate(mean, *this); }

Ziggurat::Ziggurat() {
    constexpr double r = tail_start, v = 9.91256303526217e-3;
    auto f = [](double x) { return std::exp(-0.5 * x * x); };
    x_[0] = v / f(r);
    x_[1] = r;
    for (int i = 1; i < 127; ++i) x_[i + 1] = std::sqrt(-2.0 * std::log(v / x_[i] + f(x_[i])));
    x_[128] = 0.0;
    for (int i = 0; i <= 128; ++i) f_[i] = f(x_[i]);
}

const Ziggurat& Ziggurat::instance() {
    static const Ziggurat table;
    return table;
}

double Ziggurat::slow(int layer, double x, RandomStream& more) const {
    constexpr double r = tail_start;
    for (;;) {
        if (layer == 0) {
            // The tail beyond R (Marsaglia 1964): x = −ln(u₁)/R, accept when −2 ln u₂ > x².
            for (;;) {
                const double t = -lane::log(more.uniform_open()) / r;
                const double y = -lane::log(more.uniform_open());
                if (2.0 * y > t * t) return r + t;
            }
        }
        // The wedge of layer i between f(x_i) and f(x_{i+1}): accept under the curve.
        if (f_[layer] + more.uniform() * (f_[layer + 1] - f_[layer]) < lane::exp(-0.5 * x * x))
            return x;
        // Rejected: a fresh layer and abscissa from `more`.
        const std::uint64_t word = more.next_u64();
        layer = int(word & 127);
        x = double(word >> 11) * 0x1.0p-53 * x_[layer];
        if (x < x_[layer + 1]) return x;
    }
}

}  // namespace shapesim
