// The galaxy counts of a model's real fields (morphology.hpp): completeness, density, the
// power law fitted to them by maximum likelihood (CountModel).
#include "shapesim/morphology.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/deconvolution.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/positivity.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"
#include "shapesim/version.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

namespace shapesim {

std::vector<std::size_t> fields_counted(const std::vector<SourceField>& fields, double mag) {
    double deepest = -std::numeric_limits<double>::infinity();
    for (const SourceField& f : fields) deepest = std::max(deepest, f.completeness);
    std::vector<std::size_t> counted;
    for (std::size_t k = 0; k < fields.size(); ++k)
        if (fields[k].completeness >= std::min(mag, deepest)) counted.push_back(k);
    return counted;
}

long count_shape_only(const Morphology& morphology) {
    return long(std::count_if(morphology.points.begin(), morphology.points.end(),
                              [](const MorphologyPoint& p) { return p.shape_only; }));
}

double field_density(const std::vector<SourceField>& fields, double mag_limit) {
    if (fields.empty()) return 0.0;
    if (fields.size() == 1) return fields.front().density(mag_limit);
    double brightest = mag_limit;
    for (const SourceField& f : fields)
        if (!f.mags.empty()) brightest = std::min(brightest, f.mags.front());
    constexpr double width = 0.25;
    double density = 0.0;
    // Bins (lo, hi] from just below the brightest galaxy up to the limit.
    for (double lo = std::floor(brightest / width) * width - width; lo < mag_limit; lo += width) {
        const double hi = std::min(lo + width, mag_limit);
        double count = 0.0, area = 0.0;
        for (std::size_t k : fields_counted(fields, hi)) {
            const auto& m = fields[k].mags;
            count += double(std::upper_bound(m.begin(), m.end(), hi) -
                            std::upper_bound(m.begin(), m.end(), lo));
            area += fields[k].area_arcmin2;
        }
        if (area > 0.0) density += count / area;
    }
    return density;
}

double count_turnover(const std::vector<double>& sorted_mags) {
    if (sorted_mags.size() < 10) return std::numeric_limits<double>::infinity();
    constexpr double width = 0.5;
    std::map<long, long> bins;
    for (double m : sorted_mags) ++bins[long(std::floor(m / width))];
    long best = bins.begin()->first, most = 0;
    for (const auto& [bin, n] : bins)
        if (n > most) {
            most = n;
            best = bin;
        }
    return double(best + 1) * width;
}

double power_law_magnitude(double u, double slope, double lo, double hi) {
    const double span = hi - lo;
    const double k = slope * std::log(10.0);
    if (std::abs(k * span) < 1e-9) return lo + u * span;
    // N(< m) ∝ e^{k (m − lo)} − 1, inverted.
    return lo + std::log1p(u * std::expm1(k * span)) / k;
}

namespace {

// ∫_lo^hi e^{k (m − pivot)} dm and ∫_lo^hi (m − pivot) e^{k (m − pivot)} dm, with their limits
// as k → 0.
struct PowerMoments {
    double zeroth = 0.0, first = 0.0;
};
PowerMoments power_moments(double k, double lo, double hi, double pivot) {
    const double a = lo - pivot, b = hi - pivot;
    if (std::abs(k) * std::max(std::abs(a), std::abs(b)) < 1e-7)
        return {b - a, 0.5 * (b * b - a * a)};
    const double ea = std::exp(k * a), eb = std::exp(k * b);
    // ∫ x e^{kx} dx = e^{kx} (x/k − 1/k²)
    return {(eb - ea) / k, eb * (b / k - 1.0 / (k * k)) - ea * (a / k - 1.0 / (k * k))};
}

}  // namespace

double CountModel::density(double lo, double hi) const {
    lo = std::max(lo, bright);
    hi = std::min(hi, faint);
    if (!(hi > lo)) return 0.0;
    return std::pow(10.0, log_density) *
           power_moments(slope * std::log(10.0), lo, hi, pivot).zeroth;
}

CountModel fit_counts(const std::vector<SourceField>& fields, double bright, double faint) {
    CountModel c;
    c.bright = bright;
    c.faint = faint;
    struct Range {
        double area, hi;
    };
    std::vector<Range> ranges;
    double sum = 0.0, first = std::numeric_limits<double>::infinity(), last = -first;
    for (const SourceField& f : fields) {
        const double hi = std::min(faint, f.completeness);
        if (!(hi > bright) || !(f.area_arcmin2 > 0.0)) continue;
        ranges.push_back({f.area_arcmin2, hi});
        for (double m : f.mags)
            if (m >= bright && m <= hi) {
                ++c.galaxies;
                sum += m - c.pivot;
                first = std::min(first, m);
                last = std::max(last, m);
            }
    }
    if (c.galaxies < 2 || !(last > first))
        throw Error("the fields hold " + std::to_string(c.galaxies) +
                    " galaxies of distinct magnitudes between " + std::to_string(bright) + " and " +
                    std::to_string(faint) + ": too few to fit counts to");
    const double mean = sum / double(c.galaxies);
    const double ln10 = std::log(10.0);
    // The mean magnitude (less the pivot) the power law of slope b predicts over the ranges,
    // weighted by area; it rises with b, so bisection finds the score's root.
    const auto predicted = [&](double b) {
        double zeroth = 0.0, first_moment = 0.0;
        for (const Range& r : ranges) {
            const PowerMoments m = power_moments(b * ln10, bright, r.hi, c.pivot);
            zeroth += r.area * m.zeroth;
            first_moment += r.area * m.first;
        }
        return std::make_pair(zeroth, first_moment / zeroth);
    };
    double lo = -3.0, hi = 3.0;
    for (int i = 0; i < 200 && hi - lo > 1e-13; ++i) {
        const double mid = 0.5 * (lo + hi);
        (predicted(mid).second < mean ? lo : hi) = mid;
    }
    c.slope = 0.5 * (lo + hi);
    c.log_density = std::log10(double(c.galaxies) / predicted(c.slope).first);
    return c;
}

}  // namespace shapesim
