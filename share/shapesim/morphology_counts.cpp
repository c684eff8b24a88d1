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
#include "shapesim/text_rows.hpp"
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

namespace {

// The segment of a tabulated law holding `mag`: knots i and i + 1 (the end segments extend).
std::size_t law_segment(const CountModel& c, double mag) {
    const std::size_t n = c.knot_mag.size();
    const std::size_t i =
        std::size_t(std::upper_bound(c.knot_mag.begin(), c.knot_mag.end(), mag) -
                    c.knot_mag.begin());
    return std::min(std::max(i, std::size_t(1)), n - 1) - 1;
}

// Segment i's slope d log₁₀ N / dm.
double segment_slope(const CountModel& c, std::size_t i) {
    return (c.knot_log[i + 1] - c.knot_log[i]) / (c.knot_mag[i + 1] - c.knot_mag[i]);
}

// The pieces of [lo, hi] (within [bright, faint]) between the law's knots: each one power law.
struct LawPiece {
    double lo, hi, slope, log_at_lo, density;
};
std::vector<LawPiece> law_pieces(const CountModel& c, double lo, double hi) {
    std::vector<double> edges{lo};
    for (double m : c.knot_mag)
        if (m > lo && m < hi) edges.push_back(m);
    edges.push_back(hi);
    std::vector<LawPiece> pieces;
    for (std::size_t k = 0; k + 1 < edges.size(); ++k) {
        const double a = edges[k], b = edges[k + 1];
        const double slope = segment_slope(c, law_segment(c, 0.5 * (a + b)));
        LawPiece p{a, b, slope, c.log_dndm(a), 0.0};
        p.density = std::pow(10.0, p.log_at_lo) *
                    power_moments(slope * std::log(10.0), a, b, a).zeroth;
        pieces.push_back(p);
    }
    return pieces;
}

}  // namespace

double CountModel::log_dndm(double mag) const {
    if (!tabulated()) return log_density + slope * (mag - pivot);
    const std::size_t i = law_segment(*this, mag);
    return knot_log[i] + segment_slope(*this, i) * (mag - knot_mag[i]);
}

double CountModel::density(double lo, double hi) const {
    lo = std::max(lo, bright);
    hi = std::min(hi, faint);
    if (!(hi > lo)) return 0.0;
    if (tabulated()) {
        double sum = 0.0;
        for (const LawPiece& p : law_pieces(*this, lo, hi)) sum += p.density;
        return sum;
    }
    return std::pow(10.0, log_density) *
           power_moments(slope * std::log(10.0), lo, hi, pivot).zeroth;
}

double CountModel::magnitude(double u) const {
    if (!tabulated()) return power_law_magnitude(u, slope, bright, faint);
    const std::vector<LawPiece> pieces = law_pieces(*this, bright, faint);
    double total = 0.0;
    for (const LawPiece& p : pieces) total += p.density;
    double want = u * total;
    for (const LawPiece& p : pieces) {
        if (want < p.density || &p == &pieces.back())
            return power_law_magnitude(std::min(want / p.density, 1.0), p.slope, p.lo, p.hi);
        want -= p.density;
    }
    return faint;  // no piece: bright == faint
}

CountModel count_law() {
    // COSMOS2020 (Weaver et al. 2022, Table 2), i band, "Farmer" catalogue: log₁₀ dN/dm per deg²
    // per magnitude at the 0.5-mag bins' centres; the bins fainter than 25.75 lose galaxies to
    // incompleteness (26.75: 5.35, 27.25: 5.22) and give way to the HDF-N slope.
    static const double mags[] = {19.25, 19.75, 20.25, 20.75, 21.25, 21.75, 22.25,
                                  22.75, 23.25, 23.75, 24.25, 24.75, 25.25, 25.75};
    static const double logs[] = {3.01, 3.23, 3.44, 3.64, 3.85, 4.03, 4.21,
                                  4.38, 4.54, 4.71, 4.86, 4.97, 5.08, 5.20};
    constexpr double faint_slope = 0.26;  // Marín-Franch & Aparicio 2003, HDF-N I₈₁₄ to 31
    const double per_arcmin2 = std::log10(3600.0);
    CountModel c;
    for (std::size_t i = 0; i < std::size(mags); ++i) {
        c.knot_mag.push_back(mags[i]);
        c.knot_log.push_back(logs[i] - per_arcmin2);
    }
    c.knot_mag.push_back(31.0);
    c.knot_log.push_back(c.knot_log.back() + faint_slope * (31.0 - mags[std::size(mags) - 1]));
    c.bright = 16.0;
    c.faint = 31.0;
    c.source = "COSMOS2020 i-band counts (Weaver et al. 2022), HDF-N slope 0.26 fainter than 25.75";
    return c;
}

CountModel read_count_law(const std::string& path) {
    CountModel c;
    const double per_arcmin2 = std::log10(3600.0);
    std::ifstream file(path);
    if (!file) throw Error("cannot open", path);
    for_each_text_row(file, path, [&](const std::string& line, long number) {
        std::istringstream in(line);
        double mag = 0.0, log_n = 0.0;
        std::string rest;
        if (!(in >> mag >> log_n) || (in >> rest))
            throw Error("expected 'mag log10_dN_dm' (per deg^2 per magnitude)", path, number);
        if (!std::isfinite(mag) || !std::isfinite(log_n) || std::fabs(log_n) > 100.0)
            throw Error("not a finite magnitude and log10 count", path, number);
        if (!c.knot_mag.empty() && !(mag > c.knot_mag.back()))
            throw Error("magnitudes must ascend", path, number);
        c.knot_mag.push_back(mag);
        c.knot_log.push_back(log_n - per_arcmin2);
    });
    if (c.knot_mag.size() < 2) throw Error("a count law needs two lines or more", path);
    c.bright = c.knot_mag.front() - 3.0;
    c.faint = c.knot_mag.back() + 3.0;
    c.source = path;
    return c;
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
