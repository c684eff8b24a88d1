#include "shapesim/sources.hpp"

#include "shapesim/bands.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace shapesim {

SourceRecord source_record(const Detection& object, const CoreFraction& core,
                           double stellarity_value, const CutStamp* cut,
                           const SourceContext& context) {
    SourceRecord r;
    r.id = std::to_string(object.label);
    r.x = object.x;
    r.y = object.y;
    if (context.wcs) {
        const SkyPosition sky = context.wcs->pixel_to_sky(object.x, object.y);
        r.ra = sky.ra;
        r.dec = sky.dec;
    }
    r.flux = object.flux_auto;
    r.flux_err = object.flux_auto_err;
    if (object.flux_auto > 0.0) r.mag = context.zero_point - 2.5 * std::log10(object.flux_auto);
    r.a = object.a;
    r.b = object.b;
    r.theta = object.theta;
    if (std::isfinite(object.fwhm)) r.fwhm = object.fwhm;
    r.stellarity = stellarity_value;
    r.flags = object.flags;
    if (!(object.flux_auto > 0.0)) r.flags.push_back("nonpositive_flux");
    if (cut && cut->clipped) r.flags.push_back("edge");
    if (cut && cut->noise_global) r.flags.push_back("noise_global");
    if (cut && cut->border_not_sky) r.flags.push_back("stamp_not_sky");

    Json& e = r.extra;
    e["kind"] = stellarity_value > context.star_threshold ? "star" : "galaxy";
    e["flux_iso"] = object.flux_iso;
    e["iso_area"] = object.iso_area;
    e["npix"] = object.npix;
    e["peak"] = object.peak;
    e["x_peak"] = object.x_peak;
    e["y_peak"] = object.y_peak;
    e["kron_radius"] = object.kron_radius;
    e["sigma"] = object.sigma;
    e["threshold"] = object.threshold;
    if (std::isfinite(core.ratio)) {
        e["core_fraction"] = core.ratio;
        e["core_fraction_err"] = core.error;
    }
    if (cut) {
        e["stamp_file"] = context.stamps;
        e["stamp_hdu"] = cut->stamp.id;
        e["stamp_x0"] = cut->stamp.x0;
        e["stamp_y0"] = cut->stamp.y0;
        e["stamp_nx"] = int(cut->stamp.image.cols());
        e["stamp_ny"] = int(cut->stamp.image.rows());
        e["noise_rms"] = cut->noise_rms;
        e["weight_scale"] = cut->weight_scale;
        e["border_pixels"] = cut->border_pixels;
        e["stamp_grown"] = cut->grown;
    }
    e["noise_correlation"] = context.noise_correlation;
    e["background_rms"] = context.background_rms;
    e["pixel_scale"] = context.pixel_scale;
    e["zero_point"] = context.zero_point;
    e["image"] = context.image;
    return r;
}

CatalogueTally catalogue_sources(const DetectionResult& field, const PointSourceLocus& locus,
                                 const SourceContext& context,
                                 const std::vector<BandField>& bands, const StampOptions& stamp,
                                 FitsWriter* stamps, bool stamp_stars, const SourceSink& sink,
                                 const std::vector<std::size_t>* only) {
    CatalogueTally tally;
    const std::size_t n = only ? only->size() : field.objects.size();
    for (std::size_t k = 0; k < n; ++k) {
        const Detection& object = field.objects[only ? (*only)[k] : k];
        if (is_single_pixel_event(object.peak, object.flux_iso)) {  // not a star: no PSF
            ++tally.single_pixel_events;
            continue;
        }
        const CoreFraction core = core_fraction(field, object, locus);
        const double star = stellarity(core, locus);
        // A saturated object is set aside with the stars: its shape is not its own, and its
        // wings flag the galaxies they reach (shapesim-decompose --stars: "bright_star").
        const bool saturated = std::find(object.flags.begin(), object.flags.end(),
                                         "saturated") != object.flags.end();
        const bool is_star = star > context.star_threshold || saturated;
        std::unique_ptr<CutStamp> cut;
        if (stamps && (!is_star || stamp_stars)) {
            cut = std::make_unique<CutStamp>(
                cut_stamp(field, object, std::to_string(object.label), stamp));
            write_stamp(*stamps, cut->stamp);
        }
        SourceRecord record = source_record(object, core, star, cut.get(), context);
        if (!bands.empty())
            add_bands(record, bands, std::size_t(object.label - 1), object, cut.get(), stamps,
                      context.stamps, stamp);
        if (is_star) ++tally.stars;
        if (saturated) ++tally.saturated;
        sink(object, record, is_star, star);
    }
    return tally;
}

std::optional<double> header_zero_point(FitsReader& fits) {
    for (const char* key : {"MAGZPT", "MAGZERO", "ZEROPNT", "ZP", "PHOTZP"})
        if (auto zp = fits.optional_double(key)) return zp;
    const auto flam = fits.optional_double("PHOTFLAM");
    const auto plam = fits.optional_double("PHOTPLAM");
    if (flam && plam && *flam > 0.0 && *plam > 0.0)
        return -2.5 * std::log10(*flam) - 5.0 * std::log10(*plam) - 2.408;
    return std::nullopt;
}

FieldNoise read_field_noise(const std::string& path) {
    JsonlReader reader(path, {SourceRecord::schema});
    SourceRecord r;
    std::vector<double> rms, field_rms, factor;
    while (reader.next_record(r)) {
        try {
            if (auto v = optional_double(r.extra, "background_rms"); v && *v > 0.0)
                field_rms.push_back(*v);
            if (auto v = optional_double(r.extra, "noise_rms")) rms.push_back(*v);
            if (auto v = optional_double(r.extra, "noise_correlation")) factor.push_back(*v);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    }
    if (rms.empty() && field_rms.empty())
        throw Error("no background_rms or noise_rms in the records", path);
    return {median_of_values(field_rms.empty() ? rms : field_rms),
            factor.empty() ? 1.0 : std::max(1.0, median_of_values(factor))};
}

}  // namespace shapesim
