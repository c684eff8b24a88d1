#include "shapesim/decompose_job.hpp"

#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/transform.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <memory>

namespace shapesim {

double beta_start(const SourceRecord& source) { return std::max(source.a.value_or(1.0), 0.5); }

JobReader::JobReader(JobSettings settings) : settings_(std::move(settings)) {
    if (!settings_.stamps.empty())
        stamp_files_[settings_.stamps] = std::make_unique<FitsReader>(settings_.stamps);
}

void JobReader::set_psf(const ShapeletModel& psf_arcsec) { psf_arcsec_ = psf_arcsec; }

void JobReader::add_band_psf(const std::string& band, const ShapeletModel& psf_arcsec) {
    band_psfs_[band] = psf_arcsec;
}

void JobReader::set_psf_field(std::shared_ptr<const PsfField> field) {
    psf_field_ = std::move(field);
}

void JobReader::add_band_correlation(const std::string& band,
                                     const NoiseCorrelation& correlation) {
    band_correlations_[band] = correlation;
}

// Band `band`'s PSF at `pixel_scale` (empty band: the common --psf), dilated once per scale.
std::optional<CartesianModel> JobReader::psf_at(const std::string& band, double pixel_scale) {
    const auto own = band_psfs_.find(band);
    if (band.empty() || own == band_psfs_.end()) {
        if (!psf_arcsec_) return std::nullopt;
        auto at = psfs_.find(pixel_scale);
        if (at == psfs_.end())
            at = psfs_.emplace(pixel_scale, to_cartesian(dilate(*psf_arcsec_, 1.0 / pixel_scale)))
                     .first;
        return at->second;
    }
    auto at = band_psfs_at_.find({band, pixel_scale});
    if (at == band_psfs_at_.end())
        at = band_psfs_at_
                 .emplace(std::pair(band, pixel_scale),
                          to_cartesian(dilate(own->second, 1.0 / pixel_scale)))
                 .first;
    return at->second;
}

DecomposeJob JobReader::read(const SourceRecord& source, const JsonlReader& reader) {
    // Field errors from the record's extra fields, placed at the reader's file and line.
    const auto placed = [&](const auto& read_field) {
        try {
            return read_field();
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    };
    DecomposeJob job;
    job.line = reader.line();
    std::string file = settings_.stamps;
    if (file.empty()) {
        if (!source.extra.contains("stamp_file"))
            throw Error("no stamp_file in the record: give --stamps", reader.name(),
                        reader.line(), "stamp_file");
        file = placed([&] { return required_string(source.extra, "stamp_file"); });
    }
    std::string hdu = source.id;
    if (source.extra.contains("stamp_hdu"))
        hdu = placed([&] { return required_string(source.extra, "stamp_hdu"); });
    auto& fits = stamp_files_[file];
    if (!fits) fits = std::make_unique<FitsReader>(file);
    try {
        job.stamp = read_stamp(*fits, hdu);
    } catch (const Error& e) {  // the FITS place and the record that asked for it
        throw Error(e.where_what(), reader.name(), reader.line(), "stamp_hdu");
    }
    job.forced_noise_correlation = settings_.noise_correlation;
    if (!job.forced_noise_correlation && settings_.white_noise) job.forced_noise_correlation = 1.0;
    if (job.forced_noise_correlation)
        job.noise_correlation = *job.forced_noise_correlation;
    else if (source.extra.contains("noise_correlation"))
        job.noise_correlation = std::max(
            1.0, placed([&] { return required_double(source.extra, "noise_correlation"); }));
    // Typed reads here, on the reading thread: a wrong type is a placed error, not a
    // worker's exception.
    job.pixel_scale = placed([&] {
        const auto v = optional_double(source.extra, "pixel_scale");
        if (!v || !(*v > 0.0))
            throw Error("no positive pixel_scale in the record", "", 0, "pixel_scale");
        return *v;
    });
    job.zero_point = placed([&] { return optional_double(source.extra, "zero_point"); });
    if (psf_field_) {
        // The PSF where the source is (its model is centred at 0, as set_psf's).
        job.psf = placed([&] { return psf_field_->at(source.x, source.y); });
    } else {
        job.psf = psf_at("", job.pixel_scale);
    }
    if (settings_.bands) {
        // A band without its own PSF is fitted through the common one.
        const auto psf_of = [&](const std::string& band) {
            return band_psfs_.count(band) || !psf_field_ ? psf_at(band, job.pixel_scale) : job.psf;
        };
        job.joint = placed([&] {
            std::vector<SourceBand> bands = source_bands(source);
            if (bands.empty()) return JointStamps{};
            return read_joint_stamps(std::move(bands), job.stamp, file, settings_.stamps,
                                     settings_.reference_band, stamp_files_, psf_of);
        });
        for (const SourceBand& band : job.joint.bands) {
            const auto own = band_correlations_.find(band.band);
            job.joint.correlations.push_back(
                own != band_correlations_.end() ? std::optional(own->second) : std::nullopt);
        }
    }
    job.source = source;
    return job;
}

DecomposeOutcome decompose_job(const DecomposeJob& job, const DecomposeOptions& options,
                               const std::vector<SourceRecord>& stars) {
    DecomposeOutcome out;
    try {
        DecomposeOptions fit = options;
        fit.noise_correlation = job.noise_correlation;
        fit.psf = job.psf;
        MaskArray mask = (job.stamp.mask != 0.0).cast<std::uint8_t>();
        // The detection's centre in stamp FITS coordinates.
        const double x = job.source.x - (job.stamp.x0 - 1);
        const double y = job.source.y - (job.stamp.y0 - 1);
        const double beta = beta_start(job.source);
        if (job.joint.bands.empty()) {
            out.decomposition =
                decompose(job.stamp.image, job.stamp.weight, &mask, x, y, beta, fit);
            out.record = shapelet_record(job.source, *out.decomposition, job.stamp,
                                         job.pixel_scale, job.zero_point,
                                         job.psf ? &*job.psf : nullptr);
        } else {
            auto [d, r] = decompose_joint(job.source, job.joint, job.stamp, x, y, beta, fit,
                                          job.pixel_scale, job.forced_noise_correlation);
            out.decomposition = std::move(d);
            out.record = std::move(r);
        }
        const ShapeletModel& m = out.decomposition->fit.model;
        if (near_bright_star(out.record->x, out.record->y, m.beta_pix * std::sqrt(m.n_max + 1.0),
                             job.source.flux, stars))
            out.record->flags.push_back("bright_star");
    } catch (const Error& e) {
        out.error = e.message();
    } catch (const std::exception& e) {
        // Never let a worker's exception terminate the program.
        out.error = std::string("internal error: ") + e.what();
    }
    return out;
}

void write_fit_images(FitsWriter& out, const DecomposeJob& job, const ShapeletFit& fit) {
    const std::vector<FitsKeyword> where{FitsKeyword("LTV1", 1 - job.stamp.x0),
                                         FitsKeyword("LTV2", 1 - job.stamp.y0)};
    const ImageArray& data =
        job.joint.stamps.empty() ? job.stamp.image : job.joint.stamps.front().image;
    const std::string& id = job.source.id;
    out.write_image(data, {id + ".data", -32, {}, {}, where, {}});
    out.write_image(fit.model_image, {id + ".model", -32, {}, {}, where, {}});
    out.write_image(fit.residual, {id + ".residual", -32, {}, {}, where, {}});
}

}  // namespace shapesim
