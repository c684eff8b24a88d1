#include "shapesim/records.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/record_fields.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

namespace shapesim {

namespace {

std::string number(double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
}

// The numbers' checks (Field::Check), run by validate().
void finite(std::string_view field, double v) {
    if (!std::isfinite(v)) throw Error("must be finite", {}, 0, std::string(field));
}
void non_negative(std::string_view field, double v) {
    if (!(v >= 0.0)) throw Error("must be >= 0, got " + number(v), {}, 0, std::string(field));
}
void finite_non_negative(std::string_view field, double v) {
    non_negative(field, v);
    finite(field, v);
}
void positive(std::string_view field, double v) {
    if (!(v > 0.0) || !std::isfinite(v))
        throw Error("must be finite and > 0, got " + number(v), {}, 0, std::string(field));
}
void declination(std::string_view field, double v) {
    if (!(std::abs(v) <= 90.0))
        throw Error("must be within [-90, 90] degrees, got " + number(v), {}, 0,
                    std::string(field));
}
void fraction(std::string_view field, double v) {
    if (!(v >= 0.0 && v <= 1.0))
        throw Error("must be within [0, 1], got " + number(v), {}, 0, std::string(field));
}

// n_max is checked as it is read: the coefficient arrays are sized by it.
int read_n_max(const Json& j) {
    const int n_max = required_int(j, "n_max");
    if (n_max < 0 || n_max > record_n_max_limit)
        throw Error("must be in [0, " + std::to_string(record_n_max_limit) + "], got " +
                        std::to_string(n_max),
                    {}, 0, "n_max");
    return n_max;
}

template <class Record>
void read_n_max_of(Record& r, const Json& j, NumberPairs*) {
    r.n_max = read_n_max(j);
}
template <class Record>
void write_n_max_of(const Record& r, Json& j) {
    j["n_max"] = r.n_max;
}

void check_pair_count(std::size_t count, int n_max) {
    if (count != std::size_t(polar_count(n_max)))
        throw Error("expected " + std::to_string(polar_count(n_max)) +
                        " [re, im] pairs for n_max " + std::to_string(n_max) + ", got " +
                        std::to_string(count),
                    {}, 0, "coeffs");
}

std::string coeff_field(std::size_t k) { return "coeffs[" + std::to_string(k) + "]"; }

// [[re, im], …] with exactly polar_count(n_max) pairs.
std::vector<Complex> read_coeffs(const Json& j, int n_max) {
    const Json& list = required_array(j, "coeffs");
    check_pair_count(list.size(), n_max);
    std::vector<Complex> coeffs;
    coeffs.reserve(list.size());
    for (std::size_t k = 0; k < list.size(); ++k) {
        const Json& pair = list[k];
        if (!pair.is_array() || pair.size() != 2)
            throw Error("expected a [re, im] pair, got " + pair.dump(), {}, 0, coeff_field(k));
        // The field's name is made only for an error (it is most of the time spent here).
        const auto number = [&](const Json& v) {
            return v.is_number_float() && std::isfinite(v.get<double>())
                       ? v.get<double>()
                       : as_double(v, coeff_field(k));
        };
        coeffs.emplace_back(number(pair[0]), number(pair[1]));
    }
    return coeffs;
}

// Written after `extra`, when there are any (a star's or a band's may have none).
template <class Record>
void write_coeffs_of(const Record& r, Json& j) {
    if (r.coeffs.empty()) return;
    Json list = Json::array();
    for (const auto& c : r.coeffs) list.push_back(Json::array({c.real(), c.imag()}));
    j["coeffs"] = std::move(list);
}

// The checks every shape shares (DESIGN §2; model.hpp's packed order).
void check_shape(double beta, double pixel_scale, int n_max, const std::vector<Complex>& coeffs) {
    positive("beta", beta);
    positive("pixel_scale", pixel_scale);
    if (n_max < 0 || n_max > record_n_max_limit)
        throw Error("must be in [0, " + std::to_string(record_n_max_limit) + "]", {}, 0, "n_max");
    if (coeffs.size() != std::size_t(polar_count(n_max)))
        throw Error("expected " + std::to_string(polar_count(n_max)) + " coefficients for n_max " +
                        std::to_string(n_max) + ", got " + std::to_string(coeffs.size()),
                    {}, 0, "coeffs");
    std::size_t k = 0;
    for (const auto& [n, m] : polar_indices(n_max)) {
        const Complex c = coeffs[k++];
        if (!std::isfinite(c.real()) || !std::isfinite(c.imag()))
            throw Error("must be finite", {}, 0, coeff_field(k - 1));
        // Real images: a_{n,0} = conj a_{n,0}, so its imaginary part is exactly zero.
        if (m == 0 && c.imag() != 0.0)
            throw Error(
                "a_{" + std::to_string(n) + ",0} must be real, got im = " + number(c.imag()), {}, 0,
                coeff_field(k - 1));
    }
}

// `bands` of a multi-band record of order n_max: unique names, each its coefficients.
template <class Record>
void read_bands_of(Record& r, const Json& j, NumberPairs*) {
    r.bands.clear();
    if (!j.contains("bands") || j.at("bands").is_null()) return;
    const Json& list = required_array(j, "bands");
    for (std::size_t k = 0; k < list.size(); ++k) {
        const std::string field = "bands[" + std::to_string(k) + "]";
        r.bands.push_back(BandCoefficients::from_json(list[k], r.n_max, field));
        for (std::size_t other = 0; other + 1 < r.bands.size(); ++other)
            if (r.bands[other].band == r.bands.back().band)
                throw Error("band \"" + r.bands.back().band + "\" appears twice", {}, 0, field);
    }
}

template <class Record>
void write_bands_of(const Record& r, Json& j) {
    if (r.bands.empty()) return;
    Json list = Json::array();
    for (const BandCoefficients& b : r.bands) list.push_back(b.to_json());
    j["bands"] = std::move(list);
}

// Each band's coefficients as check_shape() checks the record's own.
void check_bands(double beta, double pixel_scale, int n_max,
                 const std::vector<BandCoefficients>& bands) {
    for (std::size_t k = 0; k < bands.size(); ++k) {
        try {
            check_shape(beta, pixel_scale, n_max, bands[k].coeffs);
        } catch (const Error& e) {
            throw Error(e.message(), {}, 0, "bands[" + std::to_string(k) + "]." + e.field());
        }
    }
}

// An object's and a truth's kind.
void check_kind(const std::string& kind) {
    if (kind != "galaxy" && kind != "star")
        throw Error("must be \"galaxy\" or \"star\", got \"" + kind + "\"", {}, 0, "kind");
}

// 2√π β_pix Σ_{n even} Re a_{n,0} (DESIGN §2, §3).
double model_flux(const ShapeletModel& model) {
    double sum = 0.0;
    for (int n = 0; n <= model.n_max; n += 2) sum += model.at(n, 0).real();
    return 2.0 * std::sqrt(pi) * model.beta_pix * sum;
}

}  // namespace

// ---------------------------------------------------------------------------- SourceRecord

namespace {
const Fields<SourceRecord>& source_fields() {
    using R = SourceRecord;
    static const Fields<R> fields = {
        {"id", &R::id, FieldRule::id},
        {"x", &R::x, finite}, {"y", &R::y, finite},
        {"ra", &R::ra}, {"dec", &R::dec, declination},
        {"flux", &R::flux, finite},
        {"flux_err", &R::flux_err, non_negative},
        {"mag", &R::mag},
        {"a", &R::a, non_negative}, {"b", &R::b, non_negative},
        {"theta", &R::theta},
        {"fwhm", &R::fwhm, non_negative},
        {"stellarity", &R::stellarity, fraction},
        {"flags", &R::flags},
    };
    return fields;
}
}  // namespace

SourceRecord SourceRecord::from_json(const Json& j) {
    return read_valid_record(source_fields(), j);
}

void SourceRecord::validate() const { check_fields(source_fields(), *this); }

Json SourceRecord::to_json() const { return write_valid_record(source_fields(), *this); }

// -------------------------------------------------------------------------- ShapeletRecord

namespace {
void read_shapelet_coeffs(ShapeletRecord& r, const Json& j, NumberPairs*) {
    r.coeffs = read_coeffs(j, r.n_max);
}

const Fields<ShapeletRecord>& shapelet_fields() {
    using R = ShapeletRecord;
    static const Fields<R> fields = {
        {"id", &R::id, FieldRule::id},
        {"x", &R::x, finite}, {"y", &R::y, finite},
        {"beta", &R::beta},  // β, pixel_scale, n_max: checked with the coefficients
        {"pixel_scale", &R::pixel_scale},
        {"n_max", read_n_max_of<R>, write_n_max_of<R>},
        {"coeffs", read_shapelet_coeffs, write_coeffs_of<R>, FieldPlace::after_extra},
        {"flux", &R::flux},
        {"mag", &R::mag},
        {"chi2r", &R::chi2r, non_negative},
        {"flags", &R::flags},
        {"bands", read_bands_of<R>, write_bands_of<R>, FieldPlace::after_extra},
    };
    return fields;
}
}  // namespace

ShapeletRecord ShapeletRecord::from_json(const Json& j) {
    return read_valid_record(shapelet_fields(), j);
}

void ShapeletRecord::validate() const {
    check_fields(shapelet_fields(), *this);
    check_shape(beta, pixel_scale, n_max, coeffs);
    check_bands(beta, pixel_scale, n_max, bands);  // a model: every band its coefficients
}

Json ShapeletRecord::to_json() const { return write_valid_record(shapelet_fields(), *this); }

ShapeletModel ShapeletRecord::to_model() const {
    ShapeletModel model(x, y, beta / pixel_scale, n_max);
    model.coeffs = coeffs;
    return model;
}

ShapeletRecord ShapeletRecord::from_model(const ShapeletModel& model, double pixel_scale,
                                          std::string id) {
    model.validate();
    ShapeletRecord r;
    r.id = std::move(id);
    r.x = model.x;
    r.y = model.y;
    r.beta = model.beta_pix * pixel_scale;
    r.pixel_scale = pixel_scale;
    r.n_max = model.n_max;
    r.coeffs = model.coeffs;
    r.flux = model_flux(model);
    r.validate();
    return r;
}

// ---------------------------------------------------------------------------- ObjectRecord

namespace {
// The shape, β, pixel_scale, n_max and coefficients together: a galaxy must carry it; a star
// may (it is otherwise drawn as the PSF). The coefficients come as number pairs when
// JsonlReader read them so.
void read_object_shape(ObjectRecord& r, const Json& j, NumberPairs* pairs) {
    const bool pairs_read = pairs && pairs->found;
    if (r.kind != "galaxy" && !j.contains("coeffs") && !pairs_read) return;
    r.beta = required_double(j, "beta");
    r.pixel_scale = required_double(j, "pixel_scale");
    r.n_max = read_n_max(j);
    if (pairs_read) {
        check_pair_count(pairs->values.size(), r.n_max);
        r.coeffs = std::move(pairs->values);
    } else {
        r.coeffs = read_coeffs(j, r.n_max);
    }
}

void write_object_shape(const ObjectRecord& r, Json& j) {
    if (!r.has_shape()) return;
    j["beta"] = r.beta;
    j["pixel_scale"] = r.pixel_scale;
    j["n_max"] = r.n_max;
}

void read_lensing(ObjectRecord& r, const Json& j, NumberPairs*) {
    if (!j.contains("lensing")) return;
    const Json& l = j.at("lensing");
    if (!l.is_object())
        throw Error("must be an object {\"g1\", \"g2\", \"kappa\", \"magnify\"}", {}, 0, "lensing");
    try {
        Lensing lensing;
        lensing.g1 = required_double(l, "g1");
        lensing.g2 = required_double(l, "g2");
        lensing.kappa = optional_double(l, "kappa").value_or(0.0);
        if (l.contains("magnify")) {
            if (!l.at("magnify").is_boolean())
                throw Error("must be true or false", {}, 0, "magnify");
            lensing.conserve_flux = !l.at("magnify").get<bool>();
        }
        r.lensing = lensing;
    } catch (const Error& e) {
        throw Error(e.message(), {}, 0, "lensing." + e.field());
    }
}

void write_lensing(const ObjectRecord& r, Json& j) {
    if (!r.lensing) return;
    j["lensing"] = {{"g1", r.lensing->g1},
                    {"g2", r.lensing->g2},
                    {"kappa", r.lensing->kappa},
                    {"magnify", !r.lensing->conserve_flux}};
}

const Fields<ObjectRecord>& object_fields() {
    using R = ObjectRecord;
    static const Fields<R> fields = {
        {"id", &R::id, FieldRule::id},
        {"kind", &R::kind},
        {"ra", &R::ra, finite}, {"dec", &R::dec, declination},
        {"x", &R::x}, {"y", &R::y},
        {"mag", &R::mag},
        {"flux", &R::flux, finite},
        {"beta", read_object_shape, write_object_shape},  // with pixel_scale, n_max, coeffs
        {"pixel_scale"}, {"n_max"},
        {"coeffs", nullptr, write_coeffs_of<R>, FieldPlace::after_extra},
        {"parent", &R::parent},
        {"flags", &R::flags},
        {"lensing", read_lensing, write_lensing},
        {"bands", read_bands_of<R>, write_bands_of<R>, FieldPlace::after_extra},
    };
    return fields;
}
}  // namespace

ObjectRecord ObjectRecord::from_json(const Json& j) {
    return read_valid_record(object_fields(), j);
}

ObjectRecord ObjectRecord::from_json(const Json& j, NumberPairs& coeffs) {
    return read_valid_record(object_fields(), j, &coeffs);
}

void ObjectRecord::validate() const {
    check_fields(object_fields(), *this);
    check_kind(kind);
    // A magnitude is written with the flux drawn: a flux of 0, −0 or a denormal would turn the
    // truth's magnitude into ±∞ or NaN after the whole image was painted. Refused at the door.
    if (mag && !(flux >= std::numeric_limits<double>::min()))
        throw Error("must be a positive normal number for an object with a magnitude, got " +
                        number(flux),
                    {}, 0, "flux");
    if (kind == "galaxy" && !has_shape()) throw Error("a galaxy needs its shape", {}, 0, "coeffs");
    if (has_shape()) check_shape(beta, pixel_scale, n_max, coeffs);
    if (has_shape()) check_bands(beta, pixel_scale, n_max, bands);
    if (lensing) {
        finite("lensing.g1", lensing->g1);
        finite("lensing.g2", lensing->g2);
        finite("lensing.kappa", lensing->kappa);
        if (!(lensing->g1 * lensing->g1 + lensing->g2 * lensing->g2 < 1.0))
            throw Error("|g| must be < 1 (weak lensing), got g = (" + number(lensing->g1) + ", " +
                            number(lensing->g2) + ")",
                        {}, 0, "lensing");
        if (!(lensing->kappa < 1.0))
            throw Error("must be < 1 (weak lensing), got " + number(lensing->kappa), {}, 0,
                        "lensing.kappa");
        if (kind != "galaxy") throw Error("only galaxies are lensed", {}, 0, "lensing");
    }
}

Json ObjectRecord::to_json() const { return write_valid_record(object_fields(), *this); }

ShapeletModel ObjectRecord::to_model(double x_pix, double y_pix) const {
    if (!has_shape()) throw Error("object " + id + " has no shape", {}, 0, "coeffs");
    ShapeletModel model(x_pix, y_pix, beta / pixel_scale, n_max);
    model.coeffs = coeffs;
    return model;
}

ObjectRecord ObjectRecord::in_band(const std::string& name) const {
    for (const BandCoefficients& b : bands) {
        if (b.band != name) continue;
        if (!b.flux)
            throw Error("object " + id + "'s band \"" + name + "\" has no flux", {}, 0, "bands");
        ObjectRecord r = *this;
        r.bands.clear();
        if (has_shape()) r.coeffs = b.coeffs;
        r.flux = *b.flux;
        r.mag = b.mag;
        return r;
    }
    throw Error("object " + id + " has no band \"" + name + "\"", {}, 0, "bands");
}

// ------------------------------------------------------------------------------ BandRecord

namespace {
const Fields<BandRecord>& band_fields() {
    using R = BandRecord;
    static const Fields<R> fields = {
        {"band", &R::band},
        {"image", &R::image},
        {"weight", &R::weight, FieldRule::optional},
        {"weight_type", &R::weight_type, FieldRule::optional},
        {"zero_point", &R::zero_point, finite},
        {"gain", &R::gain, finite_non_negative},
        {"psf", &R::psf, FieldRule::optional},
    };
    return fields;
}
}  // namespace

BandRecord BandRecord::from_json(const Json& j) {
    return read_valid_record(band_fields(), j);
}

void BandRecord::validate() const {
    if (band.empty()) throw Error("must not be empty", {}, 0, "band");
    if (image.empty()) throw Error("must not be empty", {}, 0, "image");
    if (weight_type != "weight" && weight_type != "rms" && weight_type != "variance")
        throw Error("must be \"weight\", \"rms\" or \"variance\", got \"" + weight_type + "\"",
                    {}, 0, "weight_type");
    check_fields(band_fields(), *this);
}

Json BandRecord::to_json() const { return write_valid_record(band_fields(), *this); }

std::vector<BandRecord> BandRecord::read_all(const std::string& path) {
    JsonlReader reader(path, {schema});
    std::vector<BandRecord> bands;
    BandRecord r;
    while (reader.next_record(r)) {
        for (const BandRecord& other : bands)
            if (other.band == r.band)
                throw Error("band \"" + r.band + "\" appears twice", reader.name(), reader.line(),
                            "band");
        bands.push_back(r);
    }
    if (bands.empty()) throw Error("no band in the file", reader.name(), 0);
    return bands;
}

// ------------------------------------------------------------------------ BandCoefficients

namespace {
const Fields<BandCoefficients>& band_coefficient_fields() {
    using R = BandCoefficients;
    static const Fields<R> fields = {
        {"band", &R::band},
        {"flux", &R::flux},
        {"flux_err", &R::flux_err, non_negative},
        {"mag", &R::mag},
        {"chi2r", &R::chi2r, non_negative},
        {"coeffs", nullptr, write_coeffs_of<R>, FieldPlace::after_extra},  // read at n_max
    };
    return fields;
}
}  // namespace

BandCoefficients BandCoefficients::from_json(const Json& j, int n_max, const std::string& field) {
    try {
        if (!j.is_object()) throw Error("expected an object, got " + j.dump(), {}, 0, "");
        BandCoefficients b;
        read_fields(band_coefficient_fields(), j, b);
        if (b.band.empty()) throw Error("must not be empty", {}, 0, "band");
        if (j.contains("coeffs")) b.coeffs = read_coeffs(j, n_max);  // a star's: none
        check_fields(band_coefficient_fields(), b);
        b.extra = unknown_fields(band_coefficient_fields(), j);
        return b;
    } catch (const Error& e) {
        throw Error(e.message(), e.file(), e.line(),
                    field + (e.field().empty() ? "" : ".") + e.field());
    }
}

Json BandCoefficients::to_json() const {
    Json j;
    write_fields(band_coefficient_fields(), *this, j, &extra);
    return j;
}

// ----------------------------------------------------------------------------- MorphRecord

namespace {
const Fields<MorphRecord>& morph_fields() {
    using R = MorphRecord;
    static const Fields<R> fields = {
        {"id", &R::id, FieldRule::id},
        {"x", &R::x, finite}, {"y", &R::y, finite},
        {"mag", &R::mag},
        {"fwhm", &R::fwhm, non_negative},
        {"a", &R::a, non_negative}, {"b", &R::b, non_negative},
        {"theta", &R::theta},
        {"e1", &R::e1}, {"e2", &R::e2},
        {"r_petro", &R::r_petro, non_negative},
        {"c", &R::c}, {"a_sym", &R::a_sym}, {"s", &R::s}, {"gini", &R::gini}, {"m20", &R::m20},
        {"flags", &R::flags},
    };
    return fields;
}
}  // namespace

MorphRecord MorphRecord::from_json(const Json& j) {
    return read_valid_record(morph_fields(), j);
}

void MorphRecord::validate() const { check_fields(morph_fields(), *this); }

Json MorphRecord::to_json() const { return write_valid_record(morph_fields(), *this); }

// ------------------------------------------------------------------------------ TruthRecord

namespace {
// A galaxy's shape always carries its lensing error; e1, e2, rms_radius may be null.
void read_truth_shape(TruthRecord& r, const Json& j, NumberPairs*) {
    if (!j.contains("lensing_error")) return;
    // (Not emplace(): clang judges Shape not default-constructible, its member initialisers
    // being read while TruthRecord was still incomplete.)
    r.shape = TruthRecord::Shape{};
    TruthRecord::Shape& s = *r.shape;
    s.e1 = optional_double(j, "e1");
    s.e2 = optional_double(j, "e2");
    s.rms_radius = optional_double(j, "rms_radius");
    s.lensing_error = required_double(j, "lensing_error");
    // Older truth files have neither: unlensed then, unless they say otherwise.
    s.e1_intrinsic = j.contains("e1_intrinsic") ? optional_double(j, "e1_intrinsic") : s.e1;
    s.e2_intrinsic = j.contains("e2_intrinsic") ? optional_double(j, "e2_intrinsic") : s.e2;
    if (auto v = optional_double(j, "g1")) s.g1 = *v;
    if (auto v = optional_double(j, "g2")) s.g2 = *v;
    if (auto v = optional_double(j, "kappa")) s.kappa = *v;
    if (auto v = optional_double(j, "mu")) s.mu = *v;
}

void write_truth_shape(const TruthRecord& r, Json& j) {
    if (!r.shape) return;
    const TruthRecord::Shape& s = *r.shape;
    auto or_null = [](const std::optional<double>& v) { return v ? Json(*v) : Json(nullptr); };
    j["e1"] = or_null(s.e1);
    j["e2"] = or_null(s.e2);
    j["rms_radius"] = or_null(s.rms_radius);
    j["lensing_error"] = s.lensing_error;
    j["e1_intrinsic"] = or_null(s.e1_intrinsic);
    j["e2_intrinsic"] = or_null(s.e2_intrinsic);
    j["g1"] = s.g1;
    j["g2"] = s.g2;
    j["kappa"] = s.kappa;
    j["mu"] = s.mu;
}

const Fields<TruthRecord>& truth_fields() {
    using R = TruthRecord;
    static const Fields<R> fields = {
        {"id", &R::id, FieldRule::id},
        {"kind", &R::kind},
        {"ra", &R::ra}, {"dec", &R::dec, declination},
        {"x", &R::x}, {"y", &R::y},
        {"flux", &R::flux},
        {"mag", &R::mag},
        {"clipped_flux", &R::clipped_flux, non_negative},
        {"e1", read_truth_shape, write_truth_shape},  // the shape, e1 … mu together
        {"e2"}, {"rms_radius"}, {"lensing_error"}, {"e1_intrinsic"}, {"e2_intrinsic"},
        {"g1"}, {"g2"}, {"kappa"}, {"mu"},
        {"n_max", read_n_max_of<R>, write_n_max_of<R>},
        {"stamp_radius", &R::stamp_radius, non_negative},
    };
    return fields;
}
}  // namespace

TruthRecord TruthRecord::from_json(const Json& j) {
    return read_valid_record(truth_fields(), j);
}

void TruthRecord::validate() const {
    check_fields(truth_fields(), *this);
    check_kind(kind);
    if (shape) {
        non_negative("lensing_error", shape->lensing_error);
        positive("mu", shape->mu);
    }
}

Json TruthRecord::to_json() const { return write_record(truth_fields(), *this); }

// ---------------------------------------------------------------------------- field units

std::string field_unit(const std::string& field, const std::string& flux_unit) {
    static const std::map<std::string, std::string> units = {
        {"ra", "deg"},           {"dec", "deg"},           {"theta", "deg"},
        {"rotation", "deg"},     {"x", "pix"},             {"y", "pix"},
        {"a", "pix"},            {"b", "pix"},             {"fwhm", "pix"},
        {"fwhm_moffat", "pix"},  {"r_petro", "pix"},       {"rms_radius", "pix"},
        {"stamp_radius", "pix"}, {"reach", "pix"},         {"beta", "arcsec"},
        {"psf_beta", "arcsec"},  {"psf_rms_radius", "pix"}, {"shear_sigma", "pix"},
        {"pixel_scale", "arcsec/pix"}, {"mag", "mag"},     {"zero_point", "mag"}};
    if (field == "flux" || field == "flux_err" || field == "clipped_flux" || field == "flux_aper")
        return flux_unit;
    if (const auto it = units.find(field); it != units.end()) return it->second;
    if (field.rfind("mag_", 0) == 0) return "mag";
    return {};
}

// -------------------------------------------------------------- ReferenceConvolutionRecord

namespace {
// A nested record (`psf`, `result`): its errors name the path, e.g. `psf.beta`.
ShapeletRecord nested_shapelet(const Json& j, const std::string& field) {
    try {
        return ShapeletRecord::from_json(required_object(j, field));
    } catch (const Error& e) {
        if (e.field() == field) throw;
        throw Error(e.message(), e.file(), e.line(),
                    field + (e.field().empty() ? "" : ".") + e.field());
    }
}

using Convolution = ReferenceConvolutionRecord;
void read_psf(Convolution& r, const Json& j, NumberPairs*) { r.psf = nested_shapelet(j, "psf"); }
void write_psf(const Convolution& r, Json& j) { j["psf"] = r.psf.to_json(); }
void read_result(Convolution& r, const Json& j, NumberPairs*) {
    r.result = nested_shapelet(j, "result");
}
void write_result(const Convolution& r, Json& j) { j["result"] = r.result.to_json(); }

const Fields<Convolution>& convolution_fields() {
    using R = Convolution;
    static const Fields<R> fields = {
        {"galaxy_id", &R::galaxy_id, FieldRule::id},
        {"psf", read_psf, write_psf},
        {"hdu", &R::hdu},
        {"x", &R::x}, {"y", &R::y},
        {"nx", &R::nx}, {"ny", &R::ny},
        {"flux", &R::flux},
        {"result", read_result, write_result},
    };
    return fields;
}
}  // namespace

ReferenceConvolutionRecord ReferenceConvolutionRecord::from_json(const Json& j) {
    ReferenceConvolutionRecord r = read_record(convolution_fields(), j);
    if (r.nx <= 0 || r.ny <= 0) throw Error("stamp size must be positive", {}, 0, "nx");
    return r;
}

Json ReferenceConvolutionRecord::to_json() const {
    return write_record(convolution_fields(), *this);
}

bool has_flag(const std::vector<std::string>& flags, const std::string& flag) {
    return std::find(flags.begin(), flags.end(), flag) != flags.end();
}

bool has_any_flag(const std::vector<std::string>& flags, const std::string& wanted) {
    for (std::size_t start = 0;;) {
        const std::size_t bar = wanted.find('|', start);
        if (has_flag(flags, wanted.substr(start, bar - start))) return true;
        if (bar == std::string::npos) return false;
        start = bar + 1;
    }
}

}  // namespace shapesim
