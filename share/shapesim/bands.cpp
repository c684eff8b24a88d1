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
            if (inverse_variance->rows() != image.rows() ||
                inverse_variance->cols() != image.cols())
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
               const Detection& object, const CutStamp* cut, FitsWriter* stamps,
               const std::string& stamps_file, const StampOptions& options) {
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
