#include "shapesim/joint_bands.hpp"

#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace shapesim {

std::vector<SourceBand> source_bands(const SourceRecord& record) {
    std::vector<SourceBand> out;
    if (!record.extra.contains("bands")) return out;
    const Json& list = required_array(record.extra, "bands");
    for (std::size_t k = 0; k < list.size(); ++k) {
        const std::string field = "bands[" + std::to_string(k) + "]";
        try {
            const Json& e = list[k];
            if (!e.is_object()) throw Error("expected an object, got " + e.dump(), {}, 0, "");
            SourceBand b;
            b.band = required_string(e, "band");
            if (b.band.empty()) throw Error("must not be empty", {}, 0, "band");
            if (auto f = optional_string(e, "stamp_file")) b.stamp_file = *f;
            if (auto h = optional_string(e, "stamp_hdu")) b.stamp_hdu = *h;
            b.zero_point = optional_double(e, "zero_point");
            if (auto F = optional_double(e, "noise_correlation"))
                b.noise_correlation = std::max(1.0, *F);
            if (auto r = optional_double(e, "noise_rms")) b.noise_rms = *r;
            for (const SourceBand& other : out)
                if (other.band == b.band)
                    throw Error("band \"" + b.band + "\" appears twice", {}, 0, "band");
            out.push_back(std::move(b));
        } catch (const Error& e) {
            throw Error(e.message(), e.file(), e.line(),
                        field + (e.field().empty() ? "" : ".") + e.field());
        }
    }
    return out;
}

JointStamps read_joint_stamps(
    std::vector<SourceBand> bands, const Stamp& box, const std::string& record_file,
    const std::string& stamps_file, const std::string& reference, StampFiles& files,
    const std::function<std::optional<CartesianModel>(const std::string&)>& psf_of) {
    JointStamps out;
    for (const SourceBand& b : bands) {
        if (b.stamp_hdu.empty())
            throw Error("band " + b.band + " has no stamp (shapesim-detect --bands without "
                        "--stamps?)", "", 0, "bands");
        const std::string& file = !stamps_file.empty()   ? stamps_file
                                  : b.stamp_file.empty() ? record_file
                                                         : b.stamp_file;
        auto& fits = files[file];
        if (!fits) fits = std::make_unique<FitsReader>(file);
        out.stamps.push_back(read_stamp(*fits, b.stamp_hdu));
        const Stamp& stamp = out.stamps.back();
        if (stamp.x0 != box.x0 || stamp.y0 != box.y0 || stamp.image.rows() != box.image.rows() ||
            stamp.image.cols() != box.image.cols())
            throw Error("band " + b.band + "'s stamp " + b.stamp_hdu +
                            " is not in the detection stamp's box", "", 0, "bands");
        out.psfs.push_back(psf_of(b.band));
    }
    out.bands = std::move(bands);
    if (!reference.empty()) {
        const auto ref = std::find_if(out.bands.begin(), out.bands.end(),
                                      [&](const SourceBand& b) { return b.band == reference; });
        if (ref == out.bands.end())
            throw Error("no band " + reference + " (--reference-band) in the record", "", 0,
                        "bands");
        const auto k = ref - out.bands.begin();
        std::rotate(out.bands.begin(), ref, ref + 1);
        std::rotate(out.stamps.begin(), out.stamps.begin() + k, out.stamps.begin() + k + 1);
        std::rotate(out.psfs.begin(), out.psfs.begin() + k, out.psfs.begin() + k + 1);
    }
    return out;
}

std::pair<Decomposition, ShapeletRecord> decompose_joint(
    const SourceRecord& source, const JointStamps& joint, const Stamp& box, double x, double y,
    double beta_start, const DecomposeOptions& options, double pixel_scale,
    std::optional<double> noise_correlation) {
    const std::size_t n = joint.bands.size();
    std::vector<BandStamp> bands(n);
    std::vector<MaskArray> masks(n);
    std::vector<BandLabel> labels;
    for (std::size_t b = 0; b < n; ++b) {
        const SourceBand& band = joint.bands[b];
        masks[b] = (joint.stamps[b].mask != 0.0).cast<std::uint8_t>();
        bands[b] = {&joint.stamps[b].image, &joint.stamps[b].weight, &masks[b], joint.psfs[b],
                    noise_correlation.value_or(band.noise_correlation),
                    band.noise_rms > 0.0 ? 1.0 / band.noise_rms : 1.0,
                    b < joint.correlations.size() ? joint.correlations[b] : std::nullopt};
        labels.push_back({band.band, band.zero_point});
    }
    Decomposition d = decompose_bands(bands, x, y, beta_start, options);
    const auto& psf = joint.psfs.front();
    ShapeletRecord r = shapelet_record(source, d, box, pixel_scale, joint.bands.front().zero_point,
                                       psf ? &*psf : nullptr, labels);
    return {std::move(d), std::move(r)};
}

}  // namespace shapesim
