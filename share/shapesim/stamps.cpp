#include "shapesim/stamps.hpp"

#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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
}

int stamp_side(const Detection& object, const StampOptions& options) {
    const double side = options.size_factor * object.a + options.size_offset;
    // Odd, so the pixel nearest the centroid is the central one; capped well below int range.
    const int whole = int(std::min(std::ceil(side), 1.0e6));
    return std::max(3, whole % 2 == 1 ? whole : whole + 1);
}

CutStamp cut_stamp(const DetectionResult& field, const Detection& object, const std::string& id,
                   const StampOptions& options) {
    options.validate();
    const int nx = int(field.image.cols()), ny = int(field.image.rows());
    const int side = stamp_side(object, options);
    const int half = side / 2;
    const int ic = int(std::lround(object.x)) - 1, jc = int(std::lround(object.y)) - 1;
    const int i0 = std::max(0, ic - half), i1 = std::min(nx - 1, ic + half);
    const int j0 = std::max(0, jc - half), j1 = std::min(ny - 1, jc + half);
    if (i0 > i1 || j0 > j1) throw Error("object " + id + " lies outside the image");

    CutStamp out;
    out.clipped = i0 != ic - half || i1 != ic + half || j0 != jc - half || j1 != jc + half;
    Stamp& stamp = out.stamp;
    stamp.id = id;
    stamp.x0 = i0 + 1;
    stamp.y0 = j0 + 1;
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

    // Local noise from sky pixels: the stamp's border ring, then, while there are too few,
    // the sky around the stamp out to `max_margin` pixels beyond it. A sky pixel touching a
    // segment is skipped while enough others remain: the segment took its neighbours'
    // upward noise peaks, so the pixels left just outside it are biased low.
    const auto near_object = [&](int row, int column) {
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int r = row + dj, c = column + di;
                if (r >= 0 && c >= 0 && r < ny && c < nx && field.segmentation(r, c) != 0)
                    return true;
            }
        return false;
    };
    const int depth = options.border_width;
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

    std::vector<double> sigmas;
    sigmas.reserve(std::size_t(w) * std::size_t(h));
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i)
            if (stamp.weight(j, i) > 0.0) sigmas.push_back(1.0 / std::sqrt(stamp.weight(j, i)));
    if (!sigmas.empty()) {
        auto middle = sigmas.begin() + std::ptrdiff_t(sigmas.size() / 2);
        std::nth_element(sigmas.begin(), middle, sigmas.end());
        out.noise_rms = *middle;
    }
    return out;
}

}  // namespace shapesim
