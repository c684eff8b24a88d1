#include "shapesim/measure.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>

namespace shapesim {

namespace {

std::optional<double> finite(double v) {
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

}  // namespace

MorphRecord measure_object(const DetectionResult& field, const Detection& object,
                           const SourceRecord& source, const MeasureOptions& options) {
    const long nx = field.image.cols(), ny = field.image.rows();
    // statmorph's cutout around the segment's bounding box (0-based).
    const long x0 = object.xmin - 1, y0 = object.ymin - 1;
    const long dx = object.xmax - object.xmin + 1, dy = object.ymax - object.ymin + 1;
    const long xc = x0 + dx / 2, yc = y0 + dy / 2;
    const long half = std::max(long(double(std::max(dx, dy)) * options.cutout_extent / 2.0),
                               long(options.min_cutout / 2));
    const long i0 = std::max(0L, xc - half), i1 = std::min(nx, xc + half);
    const long j0 = std::max(0L, yc - half), j1 = std::min(ny, yc + half);
    const ImageArray image = field.image.block(j0, i0, j1 - j0, i1 - i0);
    const LabelArray labels = field.segmentation.block(j0, i0, j1 - j0, i1 - i0);
    MaskArray mask(j1 - j0, i1 - i0);
    for (long j = j0; j < j1; ++j)
        for (long i = i0; i < i1; ++i) mask(j - j0, i - i0) = field.is_bad(int(j), int(i)) ? 1 : 0;
    const Morphometry m = measure_morphometry(image, labels, object.label, &mask, options.morphometry);

    MorphRecord r;
    r.id = source.id;
    r.x = source.x;
    r.y = source.y;
    r.mag = source.mag;
    r.fwhm = source.fwhm;
    r.a = source.a;
    r.b = source.b;
    r.theta = source.theta;
    if (source.a && source.b && source.theta && *source.a > 0.0) {
        const double a2 = *source.a * *source.a, b2 = *source.b * *source.b;
        const double e = (a2 - b2) / (a2 + b2), t = 2.0 * *source.theta * pi / 180.0;
        r.e1 = e * std::cos(t);
        r.e2 = e * std::sin(t);
    }
    r.r_petro = finite(m.r_petro);
    r.c = finite(m.concentration);
    r.a_sym = finite(m.asymmetry);
    r.s = finite(m.clumpiness());
    r.gini = finite(m.gini);
    r.m20 = finite(m.m20);
    r.flags = m.flags;
    for (const std::string& f : source.flags) r.flags.push_back(f);
    Json& e = r.extra;
    if (source.extra.contains("kind")) e["kind"] = source.extra.at("kind");
    if (source.stellarity) e["stellarity"] = *source.stellarity;
    auto put = [&](const char* key, double v) {
        if (std::isfinite(v)) e[key] = v;
    };
    put("r20", m.r20);
    put("r80", m.r80);
    put("smoothness", m.smoothness);
    put("sky_sigma", m.sky_sigma);
    put("x_asym", m.x_asymmetry + double(i0) + 1.0);
    put("y_asym", m.y_asymmetry + double(j0) + 1.0);
    const double snr = object.flux_auto_err > 0.0 ? object.flux_auto / object.flux_auto_err : 0.0;
    put("snr", snr);

    // Reliability.
    if (!(m.r_petro >= options.min_petrosian)) r.flags.push_back("small");
    if (snr < options.min_snr) r.flags.push_back("faint");
    if (std::isfinite(m.r_petro)) {
        const double radius = options.morphometry.petro_extent * m.r_petro;
        long inside = 0, other = 0;
        // hypot(dx, dy) ≥ |dx| and ≥ |dy| (faithfully rounded, as glibc's is): rows and columns
        // farther than the radius are left out before it is computed.
        for (long j = 0; j < labels.rows(); ++j) {
            const double dy = double(j) - m.y_asymmetry;
            if (std::abs(dy) > radius) continue;
            for (long i = 0; i < labels.cols(); ++i) {
                const double dx = double(i) - m.x_asymmetry;
                if (std::abs(dx) > radius || std::hypot(dx, dy) > radius) continue;
                ++inside;
                if (labels(j, i) != 0 && labels(j, i) != object.label) ++other;
            }
        }
        if (inside > 0 && double(other) > options.max_neighbour_fraction * double(inside))
            r.flags.push_back("crowded");
    }
    return r;
}

}  // namespace shapesim
