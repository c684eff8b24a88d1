#include "shapesim/records.hpp"

#include "shapesim/constants.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

namespace shapesim {

namespace {

using Names = std::vector<std::string>;

std::string number(double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
}

// Every record names its schema; nested records (a PSF inside another line) are checked here,
// top-level lines already by JsonlReader.
void check_schema(const Json& j, const char* expected) {
    const std::string s = required_string(j, "schema");
    if (s != expected)
        throw Error(std::string("expected \"") + expected + "\", got \"" + s + "\"", {}, 0,
                    "schema");
}

// Ids are strings; an integer id (e.g. from a SExtractor-numbered catalogue) is read as its
// decimal text.
std::string read_id(const Json& j, const std::string& field = "id") {
    const auto it = j.find(field);
    if (it != j.end() && it->is_number_integer()) return it->dump();
    std::string id = required_string(j, field);
    if (id.empty()) throw Error("must not be empty", {}, 0, field);
    return id;
}

// The fields of `j` no record member reads, in their order.
Json extra_fields(const Json& j, const Names& known) {
    Json extra = Json::object();
    for (const auto& [key, value] : j.items()) {
        bool is_known = key == "schema";
        for (const auto& k : known) is_known = is_known || key == k;
        if (!is_known) extra[key] = value;
    }
    return extra;
}

void put_extra(Json& j, const Json& extra, const Names& known) {
    for (const auto& [key, value] : extra.items()) {
        bool is_known = key == "schema";
        for (const auto& k : known) is_known = is_known || key == k;
        if (!is_known) j[key] = value;
    }
}

void put(Json& j, const char* field, const std::optional<double>& value) {
    if (value) j[field] = *value;
}

int read_n_max(const Json& j) {
    const int n_max = required_int(j, "n_max");
    if (n_max < 0 || n_max > record_n_max_limit)
        throw Error("must be in [0, " + std::to_string(record_n_max_limit) + "], got " +
                        std::to_string(n_max),
                    {}, 0, "n_max");
    return n_max;
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
            return v.is_number_float() && std::isfinite(v.get<double>()) ? v.get<double>()
                                                                          : as_double(v, coeff_field(k));
        };
        coeffs.emplace_back(number(pair[0]), number(pair[1]));
    }
    return coeffs;
}

Json write_coeffs(const std::vector<Complex>& coeffs) {
    Json list = Json::array();
    for (const auto& c : coeffs) list.push_back(Json::array({c.real(), c.imag()}));
    return list;
}

// The checks every shape shares (DESIGN §2; model.hpp's packed order).
void check_shape(double beta, double pixel_scale, int n_max, const std::vector<Complex>& coeffs) {
    if (!(beta > 0.0) || !std::isfinite(beta))
        throw Error("must be finite and > 0, got " + number(beta), {}, 0, "beta");
    if (!(pixel_scale > 0.0) || !std::isfinite(pixel_scale))
        throw Error("must be finite and > 0, got " + number(pixel_scale), {}, 0, "pixel_scale");
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

void check_finite(const char* field, double v) {
    if (!std::isfinite(v)) throw Error("must be finite", {}, 0, field);
}
void check_non_negative(const char* field, const std::optional<double>& v) {
    if (v && !(*v >= 0.0)) throw Error("must be >= 0, got " + number(*v), {}, 0, field);
}
void check_dec(const char* field, const std::optional<double>& v) {
    if (v && !(std::abs(*v) <= 90.0))
        throw Error("must be within [-90, 90] degrees, got " + number(*v), {}, 0, field);
}

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

// 2√π β_pix Σ_{n even} Re a_{n,0} (DESIGN §2, §3).
double model_flux(const ShapeletModel& model) {
    double sum = 0.0;
    for (int n = 0; n <= model.n_max; n += 2) sum += model.at(n, 0).real();
    return 2.0 * std::sqrt(pi) * model.beta_pix * sum;
}

const Names source_fields = {"id",  "x", "y", "ra",    "dec",  "flux",       "flux_err",
                             "mag", "a", "b", "theta", "fwhm", "stellarity", "flags"};
const Names shapelet_fields = {"id",    "x",    "y",   "beta",  "pixel_scale", "n_max",
                               "chi2r", "flux", "mag", "flags", "coeffs",      "bands"};
const Names object_fields = {"id",   "kind",        "ra",   "dec",   "x",      "y",
                             "mag",  "flux",        "pixel_scale",   "beta",   "n_max",
                             "parent", "flags",     "coeffs",        "bands",  "lensing"};
const Names band_fields = {"band", "image", "weight", "weight_type", "zero_point", "gain", "psf"};
const Names band_coefficient_fields = {"band", "flux", "flux_err", "mag", "chi2r", "coeffs"};

// `bands` of a multi-band record of order n_max: unique names, each its coefficients.
std::vector<BandCoefficients> read_bands(const Json& j, int n_max) {
    std::vector<BandCoefficients> bands;
    if (!j.contains("bands") || j.at("bands").is_null()) return bands;
    const Json& list = required_array(j, "bands");
    for (std::size_t k = 0; k < list.size(); ++k) {
        const std::string field = "bands[" + std::to_string(k) + "]";
        bands.push_back(BandCoefficients::from_json(list[k], n_max, field));
        for (std::size_t other = 0; other + 1 < bands.size(); ++other)
            if (bands[other].band == bands.back().band)
                throw Error("band \"" + bands.back().band + "\" appears twice", {}, 0, field);
    }
    return bands;
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

void put_bands(Json& j, const std::vector<BandCoefficients>& bands) {
    if (bands.empty()) return;
    Json list = Json::array();
    for (const BandCoefficients& b : bands) list.push_back(b.to_json());
    j["bands"] = std::move(list);
}
const Names morph_fields = {"id", "x",       "y", "mag",   "fwhm", "a",    "b",   "theta", "e1",
                            "e2", "r_petro", "c", "a_sym", "s",    "gini", "m20", "flags"};
const Names truth_fields = {"id",           "kind",         "ra",    "dec",  "x",
                            "y",            "flux",         "mag",   "clipped_flux",
                            "e1",           "e2",           "rms_radius",   "lensing_error",
                            "e1_intrinsic", "e2_intrinsic", "g1",    "g2",   "kappa",
                            "mu",           "n_max",        "stamp_radius"};
const Names convolution_fields = {"galaxy_id", "psf", "hdu",  "x",     "y",
                                  "nx",        "ny",  "flux", "result"};

}  // namespace

// ---------------------------------------------------------------------------- SourceRecord

SourceRecord SourceRecord::from_json(const Json& j) {
    check_schema(j, schema);
    SourceRecord r;
    r.id = read_id(j);
    r.x = required_double(j, "x");
    r.y = required_double(j, "y");
    r.ra = optional_double(j, "ra");
    r.dec = optional_double(j, "dec");
    r.flux = required_double(j, "flux");
    r.flux_err = optional_double(j, "flux_err");
    r.mag = optional_double(j, "mag");
    r.a = optional_double(j, "a");
    r.b = optional_double(j, "b");
    r.theta = optional_double(j, "theta");
    r.fwhm = optional_double(j, "fwhm");
    r.stellarity = optional_double(j, "stellarity");
    r.flags = optional_strings(j, "flags");
    r.extra = extra_fields(j, source_fields);
    r.validate();
    return r;
}

void SourceRecord::validate() const {
    if (id.empty()) throw Error("must not be empty", {}, 0, "id");
    check_finite("x", x);
    check_finite("y", y);
    check_finite("flux", flux);
    check_dec("dec", dec);
    check_non_negative("flux_err", flux_err);
    check_non_negative("a", a);
    check_non_negative("b", b);
    check_non_negative("fwhm", fwhm);
    if (stellarity && !(*stellarity >= 0.0 && *stellarity <= 1.0))
        throw Error("must be within [0, 1], got " + number(*stellarity), {}, 0, "stellarity");
}

Json SourceRecord::to_json() const {
    validate();
    Json j;
    j["schema"] = schema;
    j["id"] = id;
    j["x"] = x;
    j["y"] = y;
    put(j, "ra", ra);
    put(j, "dec", dec);
    j["flux"] = flux;
    put(j, "flux_err", flux_err);
    put(j, "mag", mag);
    put(j, "a", a);
    put(j, "b", b);
    put(j, "theta", theta);
    put(j, "fwhm", fwhm);
    put(j, "stellarity", stellarity);
    j["flags"] = flags;
    put_extra(j, extra, source_fields);
    return j;
}

// -------------------------------------------------------------------------- ShapeletRecord

ShapeletRecord ShapeletRecord::from_json(const Json& j) {
    check_schema(j, schema);
    ShapeletRecord r;
    r.id = read_id(j);
    r.x = required_double(j, "x");
    r.y = required_double(j, "y");
    r.beta = required_double(j, "beta");
    r.pixel_scale = required_double(j, "pixel_scale");
    r.n_max = read_n_max(j);
    r.coeffs = read_coeffs(j, r.n_max);
    r.chi2r = optional_double(j, "chi2r");
    r.flux = optional_double(j, "flux");
    r.mag = optional_double(j, "mag");
    r.flags = optional_strings(j, "flags");
    r.extra = extra_fields(j, shapelet_fields);
    r.bands = read_bands(j, r.n_max);
    r.validate();
    return r;
}

void ShapeletRecord::validate() const {
    if (id.empty()) throw Error("must not be empty", {}, 0, "id");
    check_finite("x", x);
    check_finite("y", y);
    check_shape(beta, pixel_scale, n_max, coeffs);
    check_bands(beta, pixel_scale, n_max, bands);  // a model: every band its coefficients
    check_non_negative("chi2r", chi2r);
}

Json ShapeletRecord::to_json() const {
    validate();
    Json j;
    j["schema"] = schema;
    j["id"] = id;
    j["x"] = x;
    j["y"] = y;
    j["beta"] = beta;
    j["pixel_scale"] = pixel_scale;
    j["n_max"] = n_max;
    put(j, "flux", flux);
    put(j, "mag", mag);
    put(j, "chi2r", chi2r);
    j["flags"] = flags;
    put_extra(j, extra, shapelet_fields);
    j["coeffs"] = write_coeffs(coeffs);
    put_bands(j, bands);
    return j;
}

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
// An object's id (not empty) and kind (galaxy or star), as objects and truths carry them.
void check_id_and_kind(const std::string& id, const std::string& kind) {
    if (id.empty()) throw Error("must not be empty", {}, 0, "id");
    if (kind != "galaxy" && kind != "star")
        throw Error("must be \"galaxy\" or \"star\", got \"" + kind + "\"", {}, 0, "kind");
}
}  // namespace

ObjectRecord ObjectRecord::from_json(const Json& j) {
    NumberPairs none;
    return from_json(j, none);
}

ObjectRecord ObjectRecord::from_json(const Json& j, NumberPairs& coeffs) {
    check_schema(j, schema);
    ObjectRecord r;
    r.id = read_id(j);
    r.kind = required_string(j, "kind");
    r.ra = required_double(j, "ra");
    r.dec = required_double(j, "dec");
    r.x = optional_double(j, "x");
    r.y = optional_double(j, "y");
    r.mag = optional_double(j, "mag");
    r.flux = required_double(j, "flux");
    // A galaxy must carry its shape; a star may (it is otherwise drawn as the PSF).
    if (r.kind == "galaxy" || j.contains("coeffs") || coeffs.found) {
        r.beta = required_double(j, "beta");
        r.pixel_scale = required_double(j, "pixel_scale");
        r.n_max = read_n_max(j);
        if (coeffs.found) {
            check_pair_count(coeffs.values.size(), r.n_max);
            r.coeffs = std::move(coeffs.values);
        } else {
            r.coeffs = read_coeffs(j, r.n_max);
        }
    }
    r.parent = optional_string(j, "parent");
    r.flags = optional_strings(j, "flags");
    if (j.contains("lensing")) {
        const Json& l = j.at("lensing");
        if (!l.is_object())
            throw Error("must be an object {\"g1\", \"g2\", \"kappa\", \"magnify\"}", {}, 0, "lensing");
        try {
            Lensing lensing;
            lensing.g1 = required_double(l, "g1");
            lensing.g2 = required_double(l, "g2");
            lensing.kappa = optional_double(l, "kappa").value_or(0.0);
            if (l.contains("magnify")) {
                if (!l.at("magnify").is_boolean()) throw Error("must be true or false", {}, 0, "magnify");
                lensing.conserve_flux = !l.at("magnify").get<bool>();
            }
            r.lensing = lensing;
        } catch (const Error& e) {
            throw Error(e.message(), {}, 0, "lensing." + e.field());
        }
    }
    r.extra = extra_fields(j, object_fields);
    r.bands = read_bands(j, r.n_max);
    r.validate();
    return r;
}

void ObjectRecord::validate() const {
    check_id_and_kind(id, kind);
    check_finite("ra", ra);
    check_dec("dec", dec);
    check_finite("flux", flux);
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
        check_finite("lensing.g1", lensing->g1);
        check_finite("lensing.g2", lensing->g2);
        check_finite("lensing.kappa", lensing->kappa);
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

Json ObjectRecord::to_json() const {
    validate();
    Json j;
    j["schema"] = schema;
    j["id"] = id;
    j["kind"] = kind;
    j["ra"] = ra;
    j["dec"] = dec;
    put(j, "x", x);
    put(j, "y", y);
    put(j, "mag", mag);
    j["flux"] = flux;
    if (has_shape()) {
        j["beta"] = beta;
        j["pixel_scale"] = pixel_scale;
        j["n_max"] = n_max;
    }
    if (parent) j["parent"] = *parent;
    j["flags"] = flags;
    if (lensing)
        j["lensing"] = {{"g1", lensing->g1},
                        {"g2", lensing->g2},
                        {"kappa", lensing->kappa},
                        {"magnify", !lensing->conserve_flux}};
    put_extra(j, extra, object_fields);
    if (has_shape()) j["coeffs"] = write_coeffs(coeffs);
    put_bands(j, bands);
    return j;
}

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

BandRecord BandRecord::from_json(const Json& j) {
    check_schema(j, schema);
    BandRecord r;
    r.band = required_string(j, "band");
    r.image = required_string(j, "image");
    if (auto w = optional_string(j, "weight")) r.weight = *w;
    if (auto t = optional_string(j, "weight_type")) r.weight_type = *t;
    r.zero_point = optional_double(j, "zero_point");
    r.gain = optional_double(j, "gain");
    if (auto p = optional_string(j, "psf")) r.psf = *p;
    r.extra = extra_fields(j, band_fields);
    r.validate();
    return r;
}

void BandRecord::validate() const {
    if (band.empty()) throw Error("must not be empty", {}, 0, "band");
    if (image.empty()) throw Error("must not be empty", {}, 0, "image");
    if (weight_type != "weight" && weight_type != "rms" && weight_type != "variance")
        throw Error("must be \"weight\", \"rms\" or \"variance\", got \"" + weight_type + "\"",
                    {}, 0, "weight_type");
    if (zero_point) check_finite("zero_point", *zero_point);
    check_non_negative("gain", gain);
    if (gain) check_finite("gain", *gain);
}

Json BandRecord::to_json() const {
    validate();
    Json j;
    j["schema"] = schema;
    j["band"] = band;
    j["image"] = image;
    if (!weight.empty()) j["weight"] = weight;
    j["weight_type"] = weight_type;
    put(j, "zero_point", zero_point);
    put(j, "gain", gain);
    if (!psf.empty()) j["psf"] = psf;
    put_extra(j, extra, band_fields);
    return j;
}

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

BandCoefficients BandCoefficients::from_json(const Json& j, int n_max, const std::string& field) {
    try {
        if (!j.is_object()) throw Error("expected an object, got " + j.dump(), {}, 0, "");
        BandCoefficients b;
        b.band = required_string(j, "band");
        if (b.band.empty()) throw Error("must not be empty", {}, 0, "band");
        if (j.contains("coeffs")) b.coeffs = read_coeffs(j, n_max);  // a star's: none
        b.flux = optional_double(j, "flux");
        b.flux_err = optional_double(j, "flux_err");
        b.mag = optional_double(j, "mag");
        b.chi2r = optional_double(j, "chi2r");
        check_non_negative("flux_err", b.flux_err);
        check_non_negative("chi2r", b.chi2r);
        b.extra = extra_fields(j, band_coefficient_fields);
        return b;
    } catch (const Error& e) {
        throw Error(e.message(), e.file(), e.line(),
                    field + (e.field().empty() ? "" : ".") + e.field());
    }
}

Json BandCoefficients::to_json() const {
    Json j;
    j["band"] = band;
    put(j, "flux", flux);
    put(j, "flux_err", flux_err);
    put(j, "mag", mag);
    put(j, "chi2r", chi2r);
    put_extra(j, extra, band_coefficient_fields);
    if (!coeffs.empty()) j["coeffs"] = write_coeffs(coeffs);
    return j;
}

// ----------------------------------------------------------------------------- MorphRecord

MorphRecord MorphRecord::from_json(const Json& j) {
    check_schema(j, schema);
    MorphRecord r;
    r.id = read_id(j);
    r.x = required_double(j, "x");
    r.y = required_double(j, "y");
    r.mag = optional_double(j, "mag");
    r.fwhm = optional_double(j, "fwhm");
    r.a = optional_double(j, "a");
    r.b = optional_double(j, "b");
    r.theta = optional_double(j, "theta");
    r.e1 = optional_double(j, "e1");
    r.e2 = optional_double(j, "e2");
    r.r_petro = optional_double(j, "r_petro");
    r.c = optional_double(j, "c");
    r.a_sym = optional_double(j, "a_sym");
    r.s = optional_double(j, "s");
    r.gini = optional_double(j, "gini");
    r.m20 = optional_double(j, "m20");
    r.flags = optional_strings(j, "flags");
    r.extra = extra_fields(j, morph_fields);
    r.validate();
    return r;
}

void MorphRecord::validate() const {
    if (id.empty()) throw Error("must not be empty", {}, 0, "id");
    check_finite("x", x);
    check_finite("y", y);
    check_non_negative("fwhm", fwhm);
    check_non_negative("a", a);
    check_non_negative("b", b);
    check_non_negative("r_petro", r_petro);
}

Json MorphRecord::to_json() const {
    validate();
    Json j;
    j["schema"] = schema;
    j["id"] = id;
    j["x"] = x;
    j["y"] = y;
    const std::pair<const char*, const std::optional<double>*> values[] = {
        {"mag", &mag},     {"fwhm", &fwhm},   {"a", &a},   {"b", &b},
        {"theta", &theta}, {"e1", &e1},       {"e2", &e2}, {"r_petro", &r_petro},
        {"c", &c},         {"a_sym", &a_sym}, {"s", &s},   {"gini", &gini},
        {"m20", &m20}};
    for (const auto& [field, value] : values) put(j, field, *value);
    j["flags"] = flags;
    put_extra(j, extra, morph_fields);
    return j;
}

// ------------------------------------------------------------------------------ TruthRecord

TruthRecord TruthRecord::from_json(const Json& j) {
    check_schema(j, schema);
    TruthRecord r;
    r.id = read_id(j);
    r.kind = required_string(j, "kind");
    r.ra = required_double(j, "ra");
    r.dec = required_double(j, "dec");
    r.x = required_double(j, "x");
    r.y = required_double(j, "y");
    r.flux = required_double(j, "flux");
    r.mag = optional_double(j, "mag");
    r.clipped_flux = optional_double(j, "clipped_flux");
    // A galaxy's shape always carries its lensing error; e1, e2, rms_radius may be null.
    if (j.contains("lensing_error")) {
        r.shape = Shape{optional_double(j, "e1"), optional_double(j, "e2"),
                        optional_double(j, "rms_radius"), required_double(j, "lensing_error"),
                        {}, {}};
        // Older truth files have neither: unlensed then, unless they say otherwise.
        r.shape->e1_intrinsic = j.contains("e1_intrinsic") ? optional_double(j, "e1_intrinsic")
                                                           : r.shape->e1;
        r.shape->e2_intrinsic = j.contains("e2_intrinsic") ? optional_double(j, "e2_intrinsic")
                                                           : r.shape->e2;
        if (auto v = optional_double(j, "g1")) r.shape->g1 = *v;
        if (auto v = optional_double(j, "g2")) r.shape->g2 = *v;
        if (auto v = optional_double(j, "kappa")) r.shape->kappa = *v;
        if (auto v = optional_double(j, "mu")) r.shape->mu = *v;
    }
    r.n_max = read_n_max(j);
    r.stamp_radius = required_double(j, "stamp_radius");
    r.extra = extra_fields(j, truth_fields);
    r.validate();
    return r;
}

void TruthRecord::validate() const {
    check_id_and_kind(id, kind);
    check_dec("dec", dec);
    check_non_negative("clipped_flux", clipped_flux);
    check_non_negative("stamp_radius", stamp_radius);
    if (shape) {
        check_non_negative("lensing_error", shape->lensing_error);
        if (!(shape->mu > 0.0) || !std::isfinite(shape->mu))
            throw Error("must be finite and > 0, got " + number(shape->mu), {}, 0, "mu");
    }
}

Json TruthRecord::to_json() const {
    Json j;
    j["schema"] = schema;
    j["id"] = id;
    j["kind"] = kind;
    j["ra"] = ra;
    j["dec"] = dec;
    j["x"] = x;
    j["y"] = y;
    j["flux"] = flux;
    put(j, "mag", mag);
    put(j, "clipped_flux", clipped_flux);
    if (shape) {
        auto or_null = [](const std::optional<double>& v) { return v ? Json(*v) : Json(nullptr); };
        j["e1"] = or_null(shape->e1);
        j["e2"] = or_null(shape->e2);
        j["rms_radius"] = or_null(shape->rms_radius);
        j["lensing_error"] = shape->lensing_error;
        j["e1_intrinsic"] = or_null(shape->e1_intrinsic);
        j["e2_intrinsic"] = or_null(shape->e2_intrinsic);
        j["g1"] = shape->g1;
        j["g2"] = shape->g2;
        j["kappa"] = shape->kappa;
        j["mu"] = shape->mu;
    }
    j["n_max"] = n_max;
    j["stamp_radius"] = stamp_radius;
    put_extra(j, extra, truth_fields);
    return j;
}

// ---------------------------------------------------------------------------- field units

std::string field_unit(const std::string& field, const std::string& flux_unit) {
    static const std::map<std::string, std::string> units = {
        {"ra", "deg"},        {"dec", "deg"},          {"theta", "deg"},   {"rotation", "deg"},
        {"x", "pix"},         {"y", "pix"},            {"a", "pix"},       {"b", "pix"},
        {"fwhm", "pix"},      {"fwhm_moffat", "pix"},  {"r_petro", "pix"},      {"rms_radius", "pix"},
        {"stamp_radius", "pix"}, {"reach", "pix"},     {"beta", "arcsec"}, {"psf_beta", "arcsec"},
        {"psf_rms_radius", "pix"}, {"shear_sigma", "pix"},
        {"pixel_scale", "arcsec/pix"}, {"mag", "mag"}, {"zero_point", "mag"}};
    if (field == "flux" || field == "flux_err" || field == "clipped_flux" || field == "flux_aper")
        return flux_unit;
    if (const auto it = units.find(field); it != units.end()) return it->second;
    if (field.rfind("mag_", 0) == 0) return "mag";
    return {};
}

// -------------------------------------------------------------- ReferenceConvolutionRecord

ReferenceConvolutionRecord ReferenceConvolutionRecord::from_json(const Json& j) {
    check_schema(j, schema);
    ReferenceConvolutionRecord r;
    r.galaxy_id = read_id(j, "galaxy_id");
    r.psf = nested_shapelet(j, "psf");
    r.hdu = required_string(j, "hdu");
    r.x = required_double(j, "x");
    r.y = required_double(j, "y");
    r.nx = required_int(j, "nx");
    r.ny = required_int(j, "ny");
    if (r.nx <= 0 || r.ny <= 0) throw Error("stamp size must be positive", {}, 0, "nx");
    r.flux = required_double(j, "flux");
    r.result = nested_shapelet(j, "result");
    r.extra = extra_fields(j, convolution_fields);
    return r;
}

Json ReferenceConvolutionRecord::to_json() const {
    Json j;
    j["schema"] = schema;
    j["galaxy_id"] = galaxy_id;
    j["psf"] = psf.to_json();
    j["hdu"] = hdu;
    j["x"] = x;
    j["y"] = y;
    j["nx"] = nx;
    j["ny"] = ny;
    j["flux"] = flux;
    j["result"] = result.to_json();
    put_extra(j, extra, convolution_fields);
    return j;
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
