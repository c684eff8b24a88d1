#include "shapesim/stamps.hpp"

#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace shapesim {

void StampOptions::validate() const {
    if (!(size_factor >= 0.0 && std::isfinite(size_factor)))
        throw Error("stamp size factor must be ≥ 0", "", 0, "size_factor");
    if (!(size_offset >= 1.0 && std::isfinite(size_offset)))
        throw Error("stamp size offset must be ≥ 1 pixel", "", 0, "size_offset");
    if (max_margin < 0) throw Error("margin must be ≥ 0 pixels", "", 0, "max_margin");
    if (border_width < 1) throw Error("border width must be ≥ 1 pixel", "", 0, "border_width");
    if (min_border_pixels < 2)
        throw Error("the noise needs ≥ 2 border pixels", "", 0, "min_border_pixels");
    if (!(kron_factor >= 0.0 && std::isfinite(kron_factor)))
        throw Error("Kron factor must be ≥ 0", "", 0, "kron_factor");
    if (sky_margin < 0) throw Error("sky margin must be ≥ 0 pixels", "", 0, "sky_margin");
    if (!(border_sigmas > 0.0)) throw Error("must be > 0", "", 0, "border_sigmas");
    if (max_side < 3) throw Error("must be ≥ 3 pixels", "", 0, "max_side");
    if (!(gain >= 0.0 && std::isfinite(gain))) throw Error("must be ≥ 0", "", 0, "gain");
}

namespace {

// `side` rounded up to an odd whole number ≥ 3, capped well below int range.
int odd_side(double side) {
    const int whole = int(std::min(std::ceil(side), 1.0e6));
    return std::max(3, whole % 2 == 1 ? whole : whole + 1);
}

// Whether the pixel or one of its 8 neighbours belongs to an object (sky pixels are those that
// do not: a segment took its neighbours' upward noise peaks).
bool touches_object(const DetectionResult& field, int row, int column) {
    const int nx = int(field.image.cols()), ny = int(field.image.rows());
    for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
            const int r = row + dj, c = column + di;
            if (r >= 0 && c >= 0 && r < ny && c < nx && field.segmentation(r, c) != 0)
                return true;
        }
    return false;
}

// The field's pixels of box [i0, i1] × [j0, j1] (0-based, inclusive) into `stamp`: image,
// weight (inverse variance; 0 on bad pixels) and mask (other objects' segments).
void copy_stamp_pixels(const DetectionResult& field, const Detection& object, int i0, int i1,
                       int j0, int j1, Stamp& stamp) {
    const int w = i1 - i0 + 1, h = j1 - j0 + 1;
    stamp.image = field.image.block(j0, i0, h, w);
    stamp.weight.resize(h, w);
    stamp.mask = ImageArray::Zero(h, w);
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
            const int row = j0 + j, column = i0 + i;
            const double sigma = field.sigma(row, column);
            stamp.weight(j, i) =
                field.is_bad(row, column) || !std::isfinite(sigma) ? 0.0 : 1.0 / (sigma * sigma);
            const int label = field.segmentation(row, column);
            if (label != 0 && label != object.label) stamp.mask(j, i) = 1.0;
        }
}

// Local noise from sky pixels (in units of their σ): the stamp's border ring, then, while there
// are too few, the sky around the stamp out to `max_margin` pixels beyond it. A sky pixel
// touching a segment is skipped while enough others remain: the segment took its neighbours'
// upward noise peaks, so the pixels left just outside it are biased low.
std::vector<double> border_sky(const DetectionResult& field, int i0, int i1, int j0, int j1,
                               const StampOptions& options) {
    const int nx = int(field.image.cols()), ny = int(field.image.rows());
    const int depth = options.border_width;
    const auto near_object = [&](int row, int column) {
        return touches_object(field, row, column);
    };
    std::vector<double> z;
    for (const bool strict : {true, false}) {
        for (int margin = 0;; margin = std::max(2 * margin, 4)) {
            z.clear();
            const int r0 = std::max(0, j0 - margin), r1 = std::min(ny - 1, j1 + margin);
            const int c0 = std::max(0, i0 - margin), c1 = std::min(nx - 1, i1 + margin);
            for (int row = r0; row <= r1; ++row)
                for (int column = c0; column <= c1; ++column) {
                    // Inside the stamp, only its border ring.
                    if (row >= j0 + depth && row <= j1 - depth && column >= i0 + depth &&
                        column <= i1 - depth)
                        continue;
                    if (field.is_bad(row, column) || !std::isfinite(field.sigma(row, column)))
                        continue;
                    if (strict ? near_object(row, column)
                               : field.segmentation(row, column) != 0)
                        continue;
                    z.push_back(field.image(row, column) / field.sigma(row, column));
                }
            if (int(z.size()) >= options.min_border_pixels || margin >= options.max_margin)
                break;
        }
        if (int(z.size()) >= options.min_border_pixels) break;
    }
    return z;
}

// The stamp's pixel σ: the middle (upper median) of its good pixels' 1/√weight.
std::optional<double> middle_sigma(const ImageArray& weight) {
    std::vector<double> sigmas;
    sigmas.reserve(std::size_t(weight.cols()) * std::size_t(weight.rows()));
    for (int j = 0; j < int(weight.rows()); ++j)
        for (int i = 0; i < int(weight.cols()); ++i)
            if (weight(j, i) > 0.0) sigmas.push_back(1.0 / std::sqrt(weight(j, i)));
    if (sigmas.empty()) return std::nullopt;
    auto middle = sigmas.begin() + std::ptrdiff_t(sigmas.size() / 2);
    std::nth_element(sigmas.begin(), middle, sigmas.end());
    return *middle;
}

}  // namespace

// Source photon noise (see the header), from the 3×3 mean about each pixel.
void add_source_noise(Stamp& stamp, double gain) {
    const int w = int(stamp.image.cols()), h = int(stamp.image.rows());
    const ImageArray sky_weight = stamp.weight;
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
            if (!(sky_weight(j, i) > 0.0)) continue;
            double sum = 0.0;
            int n = 0;
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int r = j + dj, c = i + di;
                    if (r < 0 || c < 0 || r >= h || c >= w || !(sky_weight(r, c) > 0.0))
                        continue;
                    sum += stamp.image(r, c);
                    ++n;
                }
            const double source = std::max(0.0, sum / n);
            stamp.weight(j, i) = 1.0 / (1.0 / sky_weight(j, i) + source / gain);
        }
}

namespace {

// The stamp of pixels [i0, i1] × [j0, j1] (0-based), its weights renormalised locally and the
// source's photon noise added (see the header); `out` carries what the box choice found.
CutStamp in_box(const DetectionResult& field, const Detection& object, const std::string& id,
                int i0, int i1, int j0, int j1, const StampOptions& options, CutStamp out) {
    Stamp& stamp = out.stamp;
    stamp.id = id;
    stamp.x0 = i0 + 1;
    stamp.y0 = j0 + 1;
    copy_stamp_pixels(field, object, i0, i1, j0, j1, stamp);

    const std::vector<double> z = border_sky(field, i0, i1, j0, j1, options);
    out.border_pixels = int(z.size());
    double local = 1.0;
    if (int(z.size()) >= options.min_border_pixels) {
        const double rms = clipped_sigma(z);
        if (rms > 0.0 && std::isfinite(rms)) local = 1.0 / (rms * rms);
        else out.noise_global = true;
    } else {
        out.noise_global = true;
    }
    stamp.weight *= local;
    out.weight_scale = field.weight_scale * local;
    if (const std::optional<double> sigma = middle_sigma(stamp.weight)) out.noise_rms = *sigma;

    if (options.gain > 0.0) add_source_noise(stamp, options.gain);
    return out;
}

}  // namespace

int stamp_side(const Detection& object, const StampOptions& options) {
    return odd_side(options.size_factor * object.a + options.size_offset);
}

int extent_side(const Detection& object, const StampOptions& options) {
    const int paper = stamp_side(object, options);
    double side = paper;
    // The segment's bounding box as seen from the central pixel (a record without one, all
    // zero, has no extent to add).
    if (object.xmax > object.xmin || object.ymax > object.ymin) {
        const long ic = std::lround(object.x), jc = std::lround(object.y);
        const long reach = std::max({ic - object.xmin, object.xmax - ic, jc - object.ymin,
                                     object.ymax - jc, 0L});
        side = std::max(side, 2.0 * double(reach + options.sky_margin) + 1.0);
    }
    const double kron = options.kron_factor * object.kron_radius * object.a;
    if (std::isfinite(kron)) side = std::max(side, 2.0 * kron + 1.0);
    return std::max(paper, std::min(odd_side(side), options.max_side));
}

namespace {

// Clipped where it matters: within the paper's 3a + 5 about the centre. Sky margin and growth
// cut by the edge only cost fit pixels (a segment or aperture running off the image is flagged
// by detection itself).
bool core_clipped(const DetectionResult& field, const Detection& object,
                  const StampOptions& options) {
    const int nx = int(field.image.cols()), ny = int(field.image.rows());
    const int ic = int(std::lround(object.x)) - 1, jc = int(std::lround(object.y)) - 1;
    const int core = stamp_side(object, options) / 2;
    return ic - core < 0 || ic + core > nx - 1 || jc - core < 0 || jc + core > ny - 1;
}

}  // namespace

CutStamp cut_stamp(const DetectionResult& field, const Detection& object, const std::string& id,
                   const StampOptions& options) {
    options.validate();
    const int nx = int(field.image.cols()), ny = int(field.image.rows());
    const int ic = int(std::lround(object.x)) - 1, jc = int(std::lround(object.y)) - 1;
    const int depth = options.border_width;
    const auto near_object = [&](int row, int column) {
        return touches_object(field, row, column);
    };

    CutStamp out;
    int side = extent_side(object, options);
    int i0 = 0, i1 = -1, j0 = 0, j1 = -1;
    for (;;) {
        const int half = side / 2;
        const int a0 = std::max(0, ic - half), a1 = std::min(nx - 1, ic + half);
        const int b0 = std::max(0, jc - half), b1 = std::min(ny - 1, jc + half);
        if (a0 > a1 || b0 > b1) throw Error("object " + id + " lies outside the image");
        const bool same = a0 == i0 && a1 == i1 && b0 == j0 && b1 == j1;
        i0 = a0, i1 = a1, j0 = b0, j1 = b1;
        if (same) {  // the image's edges stop the growth
            out.border_not_sky = true;
            break;
        }
        // Is the border ring sky? Not where the object's own segment reaches it, nor where
        // its free pixels are brighter than their noise allows (wings beyond the isophote).
        bool own = false;
        double sum = 0.0;
        long n = 0;
        const auto visit = [&](int row, int column) {
            if (field.segmentation(row, column) == object.label) own = true;
            if (own || field.is_bad(row, column) || !std::isfinite(field.sigma(row, column)) ||
                near_object(row, column))
                return;
            sum += field.image(row, column) / field.sigma(row, column);
            ++n;
        };
        // The ring's sides the image's edge has not cut: an object running off the image
        // owns the pixels along that edge however large its stamp.
        const bool left = i0 == ic - half, right = i1 == ic + half;
        const bool bottom = j0 == jc - half, top = j1 == jc + half;
        for (int row = j0; row <= j1 && !own; ++row)
            for (int column = i0; column <= i1; ++column)
                if ((left && column < i0 + depth) || (right && column > i1 - depth) ||
                    (bottom && row < j0 + depth) || (top && row > j1 - depth))
                    visit(row, column);
        const bool sky = !own && (n == 0 || sum / std::sqrt(double(n)) <=
                                               options.border_sigmas * field.noise_correlation);
        if (sky || side >= options.max_side) {
            out.border_not_sky = !sky;
            break;
        }
        side = std::min(odd_side(1.25 * side), options.max_side);
        ++out.grown;
    }

    out.clipped = core_clipped(field, object, options);
    return in_box(field, object, id, i0, i1, j0, j1, options, out);
}

CutStamp cut_band_stamp(const DetectionResult& band, const Detection& object,
                        const std::string& id, const Stamp& box, const StampOptions& options) {
    options.validate();
    const int i0 = box.x0 - 1, j0 = box.y0 - 1;
    const int i1 = i0 + int(box.image.cols()) - 1, j1 = j0 + int(box.image.rows()) - 1;
    if (i0 < 0 || j0 < 0 || i1 >= band.image.cols() || j1 >= band.image.rows() || i1 < i0 ||
        j1 < j0)
        throw Error("the stamp of object " + id + " does not fit the band's image");
    CutStamp out;
    out.clipped = core_clipped(band, object, options);
    return in_box(band, object, id, i0, i1, j0, j1, options, out);
}

}  // namespace shapesim
