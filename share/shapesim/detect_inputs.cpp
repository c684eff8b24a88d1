// What detection is given besides the image, read and checked: SExtractor's filter kernels
// (.conv files), a weight, rms or variance map as inverse variance, and the options.
#include "shapesim/detect.hpp"

#include "shapesim/error.hpp"
#include "shapesim/text_rows.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace shapesim {

FilterKernel default_filter_kernel() {
    return FilterKernel{"default", 3, 3, {1, 2, 1, 2, 4, 2, 1, 2, 1}};
}

FilterKernel parse_filter_kernel(std::istream& in, const std::string& name) {
    FilterKernel kernel;
    kernel.name = name;
    bool header_seen = false;
    for_each_text_row(in, name, [&](const std::string& text, long line_number) {
        std::istringstream row(text);
        if (!header_seen) {
            std::string first, norm;
            row >> first >> norm;
            if (first != "CONV" || (norm != "NORM" && norm != "NONORM"))
                throw Error("not a SExtractor filter: first line must be CONV NORM or "
                            "CONV NONORM", name, line_number);
            header_seen = true;
            return;
        }
        std::vector<float> values;
        std::string token;
        while (row >> token) {
            char* end = nullptr;
            const double v = std::strtod(token.c_str(), &end);
            if (end == token.c_str() || *end != '\0' || !std::isfinite(v))
                throw Error("not a number: '" + token + "'", name, line_number);
            values.push_back(float(v));
        }
        if (kernel.ny == 0)
            kernel.nx = int(values.size());
        else if (int(values.size()) != kernel.nx)
            throw Error("row has " + std::to_string(values.size()) + " values, the first had " +
                            std::to_string(kernel.nx),
                        name, line_number);
        kernel.values.insert(kernel.values.end(), values.begin(), values.end());
        ++kernel.ny;
    });
    if (!header_seen) throw Error("empty filter file (no CONV line)", name);
    if (kernel.ny == 0) throw Error("filter has no rows", name);
    double sum = 0.0;
    for (float v : kernel.values) sum += std::abs(v);
    if (!(sum > 0.0)) throw Error("filter is all zeros", name);
    return kernel;
}

FilterKernel read_filter_kernel(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw Error(std::string("cannot open filter file: ") + std::strerror(errno), path);
    return parse_filter_kernel(in, path);
}

NoiseMapType parse_noise_map_type(const std::string& text) {
    if (text == "weight") return NoiseMapType::weight;
    if (text == "rms") return NoiseMapType::rms;
    if (text == "variance") return NoiseMapType::variance;
    throw Error("unknown noise map type '" + text + "' (weight, rms or variance)");
}

ImageArray inverse_variance_from(const ImageArray& map, NoiseMapType type,
                                 const std::string& place) {
    ImageArray w(map.rows(), map.cols());
    for (Eigen::Index j = 0; j < map.rows(); ++j)
        for (Eigen::Index i = 0; i < map.cols(); ++i) {
            const double v = map(j, i);
            if (v < 0.0) {
                std::ostringstream s;
                s << "negative " << (type == NoiseMapType::weight ? "weight" : "noise value")
                  << " " << v << " at pixel (" << i + 1 << ", " << j + 1 << ")";
                throw Error(s.str(), place);
            }
            double out = 0.0;
            if (std::isfinite(v) && v > 0.0) {
                switch (type) {
                    case NoiseMapType::weight: out = v; break;
                    case NoiseMapType::rms: out = 1.0 / (v * v); break;
                    case NoiseMapType::variance: out = 1.0 / v; break;
                }
                if (!std::isfinite(out)) out = 0.0;
            }
            w(j, i) = out;
        }
    return w;
}

void DetectionOptions::validate() const {
    auto fail = [](const char* field, const std::string& why) {
        throw Error(why, "", 0, field);
    };
    if (!(detect_thresh > 0.0 && std::isfinite(detect_thresh)))
        fail("DETECT_THRESH", "must be > 0");
    if (!(analysis_thresh > 0.0 && std::isfinite(analysis_thresh)))
        fail("ANALYSIS_THRESH", "must be > 0");
    if (min_area < 1) fail("DETECT_MINAREA", "must be ≥ 1");
    if (deblend_nthresh < 1) fail("DEBLEND_NTHRESH", "must be ≥ 1");
    if (!(deblend_mincont >= 0.0 && deblend_mincont <= 1.0))
        fail("DEBLEND_MINCONT", "must be in [0, 1]");
    if (!(clean_param > 0.0)) fail("CLEAN_PARAM", "must be > 0");
    if (back_size < 1) fail("BACK_SIZE", "must be ≥ 1");
    if (back_filter_size < 1) fail("BACK_FILTERSIZE", "must be ≥ 1");
    if (!(saturation > 0.0)) fail("SATUR_LEVEL", "must be > 0");
    if (filter.nx < 1 || filter.ny < 1 ||
        filter.values.size() != std::size_t(filter.nx) * std::size_t(filter.ny))
        fail("FILTER_NAME", "filter kernel is empty or inconsistent");
    if (!(kron_factor > 0.0)) fail("PHOT_AUTOPARAMS", "Kron factor must be > 0");
    if (!(kron_min_radius >= 0.0)) fail("PHOT_AUTOPARAMS", "minimum radius must be ≥ 0");
    if (!(gain >= 0.0 && std::isfinite(gain))) fail("GAIN", "must be ≥ 0");
}

}  // namespace shapesim
