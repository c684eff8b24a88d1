#include "shapesim/bands.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace shapesim {

double inner_radius(const Detection& object, const DetectionOptions& options) {
    const double r = std::max(options.kron_factor * object.kron_radius, options.kron_min_radius);
    const double a = std::max(object.a, 0.5), b = std::max(object.b, 0.5);
    // Inside the AUTO ellipse however elongated (its minor semi-axis r·b), so the outer flux is
    // an annulus's.
    return std::max(1.5, std::min(0.5 * r * std::sqrt(a * b), r * b));
}

std::vector<BandField> measure_bands(const std::vector<BandRecord>& bands,
                                     const DetectionResult& detection,
                                     const DetectionOptions& options) {
    std::vector<BandField> out;
    out.reserve(bands.size());
    for (const BandRecord& spec : bands) {
        BandField b;
        b.spec = spec;
        b.options = options;
        b.options.gain = spec.gain.value_or(0.0);
        FitsReader fits(spec.image, FitsStart::first_image);
        const ImageArray image = fits.read_image();
        std::unique_ptr<ImageArray> inverse_variance;
        if (!spec.weight.empty()) {
            FitsReader weight(spec.weight, FitsStart::first_image);
            inverse_variance = std::make_unique<ImageArray>(inverse_variance_from(
                weight.read_image(), parse_noise_map_type(spec.weight_type), weight.place()));
            if (inverse_variance->rows() != image.rows() || inverse_variance->cols() != image.cols())
                throw Error("band " + spec.band + ": the noise map's size differs from the image's",
                            weight.place());
        }
        try {
            b.field = band_field(image, inverse_variance.get(), b.options, detection);
        } catch (const Error& e) {
            throw Error("band " + spec.band + ": " + e.message(), fits.place());
        }
        b.auto_flux = forced_auto_fluxes(b.field, detection.objects, b.options);
        for (const Detection& d : detection.objects)
            b.inner_flux.push_back(
                circular_aperture_flux(b.field, d.label, d.x, d.y, inner_radius(d, b.options)));
        out.push_back(std::move(b));
    }
    return out;
}

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
            if (auto F = optional_double(e, "noise_correlation")) b.noise_correlation = std::max(1.0, *F);
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

JointStamps read_joint_stamps(std::vector<SourceBand> bands, const Stamp& box,
                              const std::string& record_file, const std::string& stamps_file,
                              const std::string& reference, StampFiles& files,
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
            throw Error("no band " + reference + " (--reference-band) in the record", "", 0, "bands");
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

std::string band_stamp_hdu(const std::string& id, const std::string& band) {
    return id + "." + band;
}

Json band_source_entry(const BandField& band, std::size_t k, const CutStamp* cut,
                       const std::string& stamps_file) {
    const ApertureFlux& f = band.auto_flux.at(k);
    Json e;
    e["band"] = band.spec.band;
    e["flux"] = f.flux;
    e["flux_err"] = f.error;
    const ApertureFlux& inner = band.inner_flux.at(k);
    e["flux_inner"] = inner.flux;
    e["flux_inner_err"] = inner.error;
    if (band.spec.zero_point && f.flux > 0.0)
        e["mag"] = *band.spec.zero_point - 2.5 * std::log10(f.flux);
    if (band.spec.zero_point) e["zero_point"] = *band.spec.zero_point;
    e["noise_correlation"] = band.field.noise_correlation;
    e["background_rms"] = band.field.background_rms;
    if (f.truncated || f.masked) {
        Json flags = Json::array();
        if (f.truncated) flags.push_back("aperture_truncated");
        if (f.masked) flags.push_back("aperture_masked");
        e["flags"] = flags;
    }
    if (cut) {
        e["stamp_file"] = stamps_file;
        e["stamp_hdu"] = cut->stamp.id;
        e["noise_rms"] = cut->noise_rms;
        e["weight_scale"] = cut->weight_scale;
        e["border_pixels"] = cut->border_pixels;
        if (cut->noise_global) e["noise_global"] = true;
    }
    return e;
}

void add_bands(SourceRecord& record, const std::vector<BandField>& bands, std::size_t k,
               const Detection& object, const CutStamp* cut, FitsWriter* stamps, const std::string& stamps_file,
               const StampOptions& options) {
    Json list = Json::array();
    for (const BandField& band : bands) {
        std::unique_ptr<CutStamp> band_cut;
        if (cut && stamps) {
            StampOptions own = options;
            own.gain = band.options.gain;
            band_cut = std::make_unique<CutStamp>(cut_band_stamp(
                band.field, object, band_stamp_hdu(record.id, band.spec.band), cut->stamp, own));
            write_stamp(*stamps, band_cut->stamp);
        }
        list.push_back(band_source_entry(band, k, band_cut.get(), stamps_file));
    }
    record.extra["bands"] = std::move(list);
}

}  // namespace shapesim
