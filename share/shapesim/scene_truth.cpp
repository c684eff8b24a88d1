// What a render writes beside its pixels: each object's truth record, the light clipped from
// dipping models, and the image's header cards (scene_image_spec).
#include "shapesim/scene.hpp"

#include "shapesim/jsonl.hpp"
#include "shapesim/transform.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

namespace shapesim {

TruthRecord truth_record(const PreparedObject& object, const ObjectRecord& record,
                         const ClippedLight& clipped) {
    TruthRecord t;
    t.id = object.id;
    t.kind = object.kind;
    t.ra = record.ra;
    t.dec = record.dec;
    t.x = object.model.x;
    t.y = object.model.y;
    // The light drawn: the model's, plus the negative light clipped away.
    t.flux = object.flux + clipped.flux;
    if (record.mag) t.mag = *record.mag - 2.5 * std::log10(t.flux / record.flux);
    if (clipped.flux > 0.0) t.clipped_flux = clipped.flux;
    if (object.intrinsic) {
        // Undefined (null) for a model whose second moments are not positive.
        auto defined = [](double v) { return std::isfinite(v) ? std::optional(v) : std::nullopt; };
        const Complex e = object.intrinsic->epsilon;
        const Complex e0 = object.unlensed_epsilon.value_or(e);
        t.shape = TruthRecord::Shape{defined(e.real()), defined(e.imag()),
                                     defined(object.intrinsic->rms_radius), object.lensing_error,
                                     defined(e0.real()), defined(e0.imag())};
        if (object.lensing) {
            t.shape->g1 = object.lensing->g1;
            t.shape->g2 = object.lensing->g2;
            t.shape->kappa = object.lensing->kappa;
            t.shape->mu = magnification(*object.lensing);
        }
    }
    if (object.psf) {
        // The PSF it was drawn with (it varies over the field): its shape and size there,
        // each left out where undefined (moments.hpp: NaN).
        const std::pair<const char*, double> psf[] = {{"psf_e1", object.psf->epsilon.real()},
                                                      {"psf_e2", object.psf->epsilon.imag()},
                                                      {"psf_rms_radius", object.psf->rms_radius}};
        for (const auto& [name, value] : psf)
            if (std::isfinite(value)) t.extra[name] = value;
    }
    t.n_max = object.model.n_max;
    t.stamp_radius = object.radius;
    // A ring's members (shapesim-sample --ring) stay together in a calibration's bootstrap.
    if (const auto ring = record.extra.find("ring"); ring != record.extra.end())
        t.extra["ring"] = *ring;
    return t;
}

std::vector<TruthRecord> truth_records(const RenderedScene& scene,
                                       const std::vector<ObjectRecord>& records) {
    std::vector<TruthRecord> truths;
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
        const PreparedObject& p = scene.objects[i];
        if (scene.window.owns(p.model.x, p.model.y))
            truths.push_back(truth_record(p, records[p.index], scene.clipped[i]));
    }
    return truths;
}

std::optional<double> objects_zero_point(const std::vector<ObjectRecord>& records) {
    std::optional<double> zero_point;
    for (const ObjectRecord& r : records) {
        if (!r.mag || !(r.flux > 0.0)) continue;
        const double zp = *r.mag + 2.5 * std::log10(r.flux);
        if (!zero_point) zero_point = zp;
        else if (std::abs(zp - *zero_point) > 1e-6) return std::nullopt;
    }
    return zero_point;
}

ClippedSummary summarise_clipped(const RenderedScene& scene) {
    ClippedSummary summary;
    for (std::size_t i = 0; i < scene.clipped.size(); ++i) {
        const ClippedLight& c = scene.clipped[i];
        if (!(c.flux > 0.0)) continue;
        ++summary.galaxies;
        summary.largest = std::max(summary.largest, c.flux / std::abs(scene.objects[i].flux));
        summary.deepest = std::min(summary.deepest, c.deepest);
    }
    return summary;
}

void write_truth_records(std::ostream& out, const std::string& name, const RenderedScene& scene,
                         const std::vector<ObjectRecord>& records) {
    JsonlWriter writer(out, name);
    for (const TruthRecord& t : truth_records(scene, records)) writer.write(t.to_json());
}

FitsImageSpec scene_image_spec(const RenderedScene& scene, const std::vector<ObjectRecord>& records,
                               const SceneOptions& o, const SceneKernels& kernels,
                               const SceneLabels& labels, int bitpix) {
    FitsImageSpec spec;
    spec.extname = "SCI";
    spec.bitpix = bitpix;
    // A field made --like an image keeps its units, unless the caller names them.
    spec.bunit = labels.bunit.empty() ? scene.field.bunit : labels.bunit;
    spec.wcs = scene.field.wcs.cutout(scene.window.x0, scene.window.y0);
    const Tile& w = scene.window;
    spec.keywords = {
        FitsKeyword("SEED", std::to_string(labels.seed), "run seed (shapesim)"),
        FitsKeyword("NOBJ", (long long)(scene.objects.size()), "objects drawn in this image"),
        FitsKeyword("TRUNC", o.truncation, "stamp truncation, fraction of noise rms or peak"),
        FitsKeyword("NOISERMS", o.noise_free ? 0.0 : o.noise_rms, "Gaussian background rms"),
        FitsKeyword("NOISECOR", o.noise_correlation, "correlated-noise factor F (4x4 blocks)"),
        FitsKeyword("NOISEMOD", labels.noise, "background noise correlation"),
        FitsKeyword("GAIN", o.noise_free ? 0.0 : o.gain, "electrons per image unit (photon noise)"),
        FitsKeyword("SKY", o.noise_free ? 0.0 : o.sky, "sky level added"),
        FitsKeyword("NOISEFRE", o.noise_free, "noise-free image"),
        FitsKeyword("G1", o.lensing ? o.lensing->g1 : 0.0, "reduced shear applied"),
        FitsKeyword("G2", o.lensing ? o.lensing->g2 : 0.0, "reduced shear applied"),
        FitsKeyword("KAPPA", o.lensing ? o.lensing->kappa : 0.0, "convergence applied"),
        FitsKeyword("LENSTOL", o.lensing_tolerance, "lensing projection tolerance"),
        FitsKeyword("PSF", labels.psf, "PSF record"),
        FitsKeyword("GALKERN", kernels.galaxy_note, "what galaxies were convolved with"),
        FitsKeyword("TILEX0", (long long)w.x0, "first field column of this image"),
        FitsKeyword("TILEY0", (long long)w.y0, "first field row of this image"),
        FitsKeyword("FIELDNX", (long long)scene.field.nx, "field width, pixels"),
        FitsKeyword("FIELDNY", (long long)scene.field.ny, "field height, pixels"),
    };
    if (!labels.band.empty())
        spec.keywords.emplace_back("BAND", labels.band, "band of the objects drawn");
    if (o.saturation > 0.0 && !o.noise_free)
        spec.keywords.emplace_back("SATURATE", o.saturation, "full well: pixels are at most this");
    if (labels.exposure_time > 0.0)
        spec.keywords.emplace_back("EXPTIME", labels.exposure_time, "exposure time, seconds");
    if (const std::optional<double> zero_point = objects_zero_point(records)) {
        const double zp = std::round(*zero_point * 1e6) / 1e6;
        spec.keywords.emplace_back("MAGZERO", zp,
                                   "AB zero point: mag = MAGZERO - 2.5 log10(value)");
        spec.keywords.emplace_back("PHOTZP", zp, "AB zero point (as MAGZERO)");
    }
    return spec;
}

}  // namespace shapesim
