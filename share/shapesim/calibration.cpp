#include "shapesim/calibration.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace shapesim {

std::vector<long> match_nearest(const std::vector<double>& truth_x,
                                const std::vector<double>& truth_y,
                                const std::vector<double>& measured_x,
                                const std::vector<double>& measured_y, double radius) {
    require(radius > 0.0 && std::isfinite(radius), "match: the radius must be finite and > 0");
    require(truth_x.size() == truth_y.size() && measured_x.size() == measured_y.size(),
            "match: x and y must be the same length");
    for (const auto* v : {&truth_x, &truth_y, &measured_x, &measured_y})
        for (double p : *v)
            if (!std::isfinite(p) || std::abs(p) > 1e15)
                throw Error("match: a position is not finite");
    // Cells one radius wide: a match lies in the 3 × 3 cells about the measurement's own.
    auto cell = [radius](double x, double y) {
        const std::int64_t i = std::int64_t(std::floor(x / radius)),
                           j = std::int64_t(std::floor(y / radius));
        return std::pair{i, j};
    };
    auto key = [](std::int64_t i, std::int64_t j) {
        return std::uint64_t(i) * 0x9E3779B97F4A7C15ULL ^
               (std::uint64_t(j) + 0x632BE59BD9B4E019ULL);
    };
    std::unordered_map<std::uint64_t, std::vector<long>> cells;
    cells.reserve(truth_x.size());
    for (std::size_t t = 0; t < truth_x.size(); ++t) {
        const auto [i, j] = cell(truth_x[t], truth_y[t]);
        cells[key(i, j)].push_back(long(t));
    }
    const double r2 = radius * radius;
    std::vector<long> match(measured_x.size(), -1);
    std::vector<double> distance(measured_x.size(), std::numeric_limits<double>::infinity());
    for (std::size_t k = 0; k < measured_x.size(); ++k) {
        const auto [i, j] = cell(measured_x[k], measured_y[k]);
        for (std::int64_t di = -1; di <= 1; ++di)
            for (std::int64_t dj = -1; dj <= 1; ++dj) {
                const auto it = cells.find(key(i + di, j + dj));
                if (it == cells.end()) continue;
                for (long t : it->second) {
                    const double dx = truth_x[std::size_t(t)] - measured_x[k];
                    const double dy = truth_y[std::size_t(t)] - measured_y[k];
                    const double d2 = dx * dx + dy * dy;
                    // Same key in another cell (a hash collision) is harmless: the distance
                    // decides.
                    if (d2 <= r2 && (d2 < distance[k] || (d2 == distance[k] && t < match[k]))) {
                        distance[k] = d2;
                        match[k] = t;
                    }
                }
            }
    }
    // One measurement per galaxy: the nearer keeps it.
    std::unordered_map<long, std::size_t> owner;
    for (std::size_t k = 0; k < match.size(); ++k) {
        if (match[k] < 0) continue;
        const auto [it, inserted] = owner.emplace(match[k], k);
        if (inserted) continue;
        const std::size_t other = it->second;
        if (distance[k] < distance[other]) {
            match[other] = -1;
            it->second = k;
        } else {
            match[k] = -1;
        }
    }
    return match;
}

namespace {

// The least-squares line e = a g + b over the points with the given multiplicities.
struct Line {
    double slope = 0.0, intercept = 0.0;
    bool defined = false;
};

Line fit_line(const std::vector<ShearPoint>& points, const std::vector<double>& weight,
              int component) {
    double sw = 0.0, sg = 0.0, se = 0.0;
    for (std::size_t k = 0; k < points.size(); ++k) {
        if (weight[k] == 0.0) continue;
        const double g = component == 1 ? points[k].g1 : points[k].g2;
        const double e = component == 1 ? points[k].e1 : points[k].e2;
        sw += weight[k];
        sg += weight[k] * g;
        se += weight[k] * e;
    }
    Line line;
    if (!(sw > 0.0)) return line;
    const double gm = sg / sw, em = se / sw;
    double sgg = 0.0, sge = 0.0;
    for (std::size_t k = 0; k < points.size(); ++k) {
        if (weight[k] == 0.0) continue;
        const double g = (component == 1 ? points[k].g1 : points[k].g2) - gm;
        const double e = (component == 1 ? points[k].e1 : points[k].e2) - em;
        sgg += weight[k] * g * g;
        sge += weight[k] * g * e;
    }
    // g must vary beyond rounding: relative to its own size.
    if (!(sgg > 1e-24 * sw * std::max(1e-12, gm * gm))) return line;
    line.slope = sge / sgg;
    line.intercept = em - line.slope * gm;
    line.defined = true;
    return line;
}

double standard_deviation(const std::vector<double>& v) {
    if (v.size() < 2) return 0.0;
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / double(v.size());
    double s = 0.0;
    for (double x : v) s += (x - mean) * (x - mean);
    return std::sqrt(s / double(v.size() - 1));
}

}  // namespace

ShearCalibration fit_shear_calibration(const std::vector<ShearPoint>& points, int resamples,
                                       std::uint64_t seed) {
    if (points.size() < 3)
        throw Error("only " + std::to_string(points.size()) +
                    " matched galaxies: m and c need more");
    require(resamples >= 0 && resamples <= 100000, "calibration: resamples must be in [0, 100000]");
    for (const ShearPoint& p : points)
        if (!std::isfinite(p.g1) || !std::isfinite(p.g2) || !std::isfinite(p.e1) ||
            !std::isfinite(p.e2))
            throw Error("a matched galaxy's shear or ellipticity is not finite");
    ShearCalibration out;
    out.galaxies = long(points.size());
    const std::vector<double> ones(points.size(), 1.0);
    const Line l1 = fit_line(points, ones, 1), l2 = fit_line(points, ones, 2);
    if (!l1.defined || !l2.defined)
        throw Error(std::string("the true g") + (l1.defined ? "2" : "1") +
                    " takes one value: m and c need the shear to vary (a shear field, halos, or "
                    "several images with different shears)");
    out.one = {l1.slope - 1.0, l1.intercept, 0.0, 0.0};
    out.two = {l2.slope - 1.0, l2.intercept, 0.0, 0.0};

    // Blocks: the points of each block, in order of first appearance.
    std::unordered_map<std::uint64_t, std::size_t> block_of;
    std::vector<std::vector<std::size_t>> blocks;
    for (std::size_t k = 0; k < points.size(); ++k) {
        const auto [it, inserted] = block_of.emplace(points[k].block, blocks.size());
        if (inserted) blocks.emplace_back();
        blocks[it->second].push_back(k);
    }
    out.blocks = long(blocks.size());
    if (resamples == 0 || blocks.size() < 2) return out;
    RandomStream stream(seed, 0, "calibration bootstrap");
    std::vector<double> m1, c1, m2, c2, weight(points.size());
    for (int r = 0; r < resamples; ++r) {
        std::fill(weight.begin(), weight.end(), 0.0);
        for (std::size_t b = 0; b < blocks.size(); ++b)
            for (std::size_t k : blocks[stream.uniform_index(blocks.size())]) weight[k] += 1.0;
        const Line a = fit_line(points, weight, 1), c = fit_line(points, weight, 2);
        if (a.defined) {
            m1.push_back(a.slope - 1.0);
            c1.push_back(a.intercept);
        }
        if (c.defined) {
            m2.push_back(c.slope - 1.0);
            c2.push_back(c.intercept);
        }
    }
    out.one.m_err = standard_deviation(m1);
    out.one.c_err = standard_deviation(c1);
    out.two.m_err = standard_deviation(m2);
    out.two.c_err = standard_deviation(c2);
    return out;
}

std::vector<CalibrationBin> fit_in_bins(const std::vector<ShearPoint>& points,
                                        const std::vector<double>& value, int bins,
                                        int resamples, std::uint64_t seed) {
    require(value.size() == points.size(), "calibration bins: one value per point");
    require(bins >= 1 && bins <= 100, "calibration bins: 1 to 100 bins");
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < value.size(); ++k)
        if (std::isfinite(value[k])) order.push_back(k);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return value[a] < value[b]; });
    std::vector<CalibrationBin> out;
    for (int b = 0; b < bins; ++b) {
        const std::size_t lo = order.size() * std::size_t(b) / std::size_t(bins);
        const std::size_t hi = order.size() * std::size_t(b + 1) / std::size_t(bins);
        CalibrationBin bin;
        bin.galaxies = long(hi - lo);
        if (hi == lo) {
            out.push_back(bin);
            continue;
        }
        bin.lo = value[order[lo]];
        bin.hi = value[order[hi - 1]];
        std::vector<ShearPoint> subset;
        for (std::size_t k = lo; k < hi; ++k) subset.push_back(points[order[k]]);
        try {
            bin.fit = fit_shear_calibration(subset, resamples, seed + std::uint64_t(b) + 1);
        } catch (const Error&) {
            // Too few galaxies, or one shear: this bin has no fit (the table says so).
        }
        out.push_back(bin);
    }
    return out;
}

}  // namespace shapesim
