// The morphology PDF as a JSON document (shapesim.morphology/1, morphology.hpp): written,
// read and checked field by field.
#include "shapesim/morphology.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/deconvolution.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/positivity.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"
#include "shapesim/version.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

namespace shapesim {

Json Morphology::to_json() const {
    Json doc = Json::object();
    doc["schema"] = schema;
    doc["n_max"] = n_max;
    if (zero_point) doc["zero_point"] = *zero_point;
    if (frame != "observed") doc["frame"] = frame;
    Json lam = Json::object();
    lam["phase_deg"] = lambda.phase_deg;
    lam["beta"] = lambda.beta;
    lam["mag"] = lambda.mag;
    lam["coefficient"] = lambda.coefficient;
    if (!bands.empty()) lam["colour"] = lambda.colour;
    doc["lambda"] = lam;
    if (!bands.empty()) {
        Json list = Json::array();
        for (std::size_t b = 0; b < bands.size(); ++b) {
            Json j = {{"band", bands[b]}};
            if (band_zero_points[b]) j["zero_point"] = *band_zero_points[b];
            list.push_back(std::move(j));
        }
        doc["bands"] = std::move(list);
        if (reference_band) {
            Json covariance = Json::array();
            for (Eigen::Index i = 0; i < colour_covariance.rows(); ++i) {
                Json row = Json::array();
                for (Eigen::Index j = 0; j < colour_covariance.cols(); ++j)
                    row.push_back(colour_covariance(i, j));
                covariance.push_back(std::move(row));
            }
            doc["colours"] = {{"reference", bands[*reference_band]},
                              {"mean", colour_mean},
                              {"covariance", std::move(covariance)}};
        }
    }
    Json pts = Json::array();
    for (const auto& p : points) {
        Json shape = Json::array();
        for (const Complex& c : p.shape) shape.push_back(Json::array({c.real(), c.imag()}));
        pts.push_back({{"id", p.id},
                       {"n_max", p.n_max},
                       {"beta", p.beta},
                       {"mag", p.mag},
                       {"weight", p.weight},
                       {"rotation", p.alignment.rotation},
                       {"reflected", p.alignment.reflected},
                       {"shape", shape}});
        if (p.psf_beta > 0.0) pts.back()["psf_beta"] = p.psf_beta;
        if (p.positivity_change > 0.0) pts.back()["positivity_change"] = p.positivity_change;
        if (!p.band_shapes.empty()) {
            Json list = Json::array();
            for (const auto& band : p.band_shapes) {
                Json pairs = Json::array();
                for (const Complex& c : band) pairs.push_back(Json::array({c.real(), c.imag()}));
                list.push_back(std::move(pairs));
            }
            pts.back()["bands"] = std::move(list);
        }
        if (p.shape_only) pts.back()["shape_only"] = true;
    }
    doc["points"] = pts;
    if (!source_fields.empty()) {
        Json fields = Json::array();
        for (const SourceField& f : source_fields) {
            Json j = {{"area_arcmin2", f.area_arcmin2}, {"mags", f.mags}};
            if (!f.image.empty()) j["image"] = f.image;
            if (std::isfinite(f.completeness)) j["completeness"] = f.completeness;
            if (f.star_mags) j["star_mags"] = *f.star_mags;
            fields.push_back(std::move(j));
        }
        // One plain field keeps the first version's form.
        if (source_fields.size() == 1 && source_fields[0].image.empty() &&
            !std::isfinite(source_fields[0].completeness))
            doc["source_field"] = fields[0];
        else
            doc["source_fields"] = fields;
    }
    if (!shape_fields.empty()) doc["shape_fields"] = shape_fields;
    doc["provenance"] = provenance;
    return doc;
}

namespace {

double number(const Json& object, const char* field, const std::string& where) {
    if (!object.is_object() || !object.contains(field) || !object.at(field).is_number())
        throw Error("missing or not a number", "", 0, where + field);
    const double v = object.at(field).get<double>();
    if (!std::isfinite(v)) throw Error("not finite", "", 0, where + field);
    return v;
}

// "colours": {"reference": band, "mean": [one per band], "covariance": [[…] one row per band]}.
void read_colour_population(Morphology& m, const Json& colours) {
    const std::size_t n = m.bands.size();
    if (!colours.is_object() || !colours.contains("reference") ||
        !colours.at("reference").is_string())
        throw Error("missing or not a string", "", 0, "colours.reference");
    const auto at =
        std::find(m.bands.begin(), m.bands.end(), colours.at("reference").get<std::string>());
    if (at == m.bands.end()) throw Error("not one of the bands", "", 0, "colours.reference");
    m.reference_band = std::size_t(at - m.bands.begin());
    const auto numbers = [](const Json& list, std::size_t size, const std::string& where) {
        if (!list.is_array() || list.size() != size)
            throw Error("must be an array of one number per band", "", 0, where);
        std::vector<double> out;
        for (const Json& v : list) {
            if (!v.is_number() || !std::isfinite(v.get<double>()))
                throw Error("not a finite number", "", 0, where);
            out.push_back(v.get<double>());
        }
        return out;
    };
    m.colour_mean =
        numbers(colours.contains("mean") ? colours.at("mean") : Json(), n, "colours.mean");
    const Json& rows = colours.contains("covariance") ? colours.at("covariance") : Json();
    if (!rows.is_array() || rows.size() != n)
        throw Error("must hold one row per band", "", 0, "colours.covariance");
    m.colour_covariance.resize(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t i = 0; i < n; ++i) {
        const std::vector<double> row = numbers(rows[i], n, "colours.covariance");
        for (std::size_t j = 0; j < n; ++j)
            m.colour_covariance(Eigen::Index(i), Eigen::Index(j)) = row[j];
    }
    if (!m.colour_covariance.isApprox(m.colour_covariance.transpose()))
        throw Error("must be symmetric", "", 0, "colours.covariance");
}

}  // namespace

namespace {

// Shape coefficients as [re, im] pairs of finite numbers; errors name `field`.
std::vector<Complex> read_complex_pairs(const Json& list, const std::string& field) {
    std::vector<Complex> shape;
    for (const Json& c : list) {
        if (!c.is_array() || c.size() != 2 || !c[0].is_number() || !c[1].is_number())
            throw Error("must hold [re, im] pairs of numbers", "", 0, field);
        const Complex v(c[0].get<double>(), c[1].get<double>());
        if (!std::isfinite(v.real()) || !std::isfinite(v.imag()))
            throw Error("not finite", "", 0, field);
        shape.push_back(v);
    }
    return shape;
}

// "lambda": the smoothing lengths (its colour width is the bands', read with them).
void read_lambda(const Json& doc, Morphology& m) {
    if (!doc.contains("lambda")) throw Error("missing", "", 0, "lambda");
    const Json& lam = doc.at("lambda");
    m.lambda.phase_deg = number(lam, "phase_deg", "lambda.");
    m.lambda.beta = number(lam, "beta", "lambda.");
    m.lambda.mag = number(lam, "mag", "lambda.");
    if (!lam.contains("coefficient") || !lam.at("coefficient").is_array() ||
        lam.at("coefficient").size() != std::size_t(polar_count(m.n_max)))
        throw Error("must be an array of polar_count(n_max) numbers", "", 0, "lambda.coefficient");
    for (const Json& v : lam.at("coefficient")) {
        if (!v.is_number() || !(v.get<double>() >= 0.0))
            throw Error("must be numbers ≥ 0", "", 0, "lambda.coefficient");
        m.lambda.coefficient.push_back(v.get<double>());
    }
    if (m.lambda.phase_deg < 0 || m.lambda.beta < 0 || m.lambda.mag < 0)
        throw Error("smoothing lengths must be ≥ 0", "", 0, "lambda");
}

// A multi-band model's "bands", their colour kernel's width and the colour population.
void read_bands(const Json& doc, Morphology& m) {
    const Json& list = doc.at("bands");
    const Json& lam = doc.at("lambda");
    if (!list.is_array() || list.empty()) throw Error("must be a non-empty array", "", 0, "bands");
    for (std::size_t b = 0; b < list.size(); ++b) {
        const std::string where = "bands[" + std::to_string(b) + "]";
        if (!list[b].is_object() || !list[b].contains("band") || !list[b].at("band").is_string())
            throw Error("missing or not a string", "", 0, where + ".band");
        m.bands.push_back(list[b].at("band").get<std::string>());
        m.band_zero_points.push_back(list[b].contains("zero_point")
                                         ? std::optional(number(list[b], "zero_point", where + "."))
                                         : std::nullopt);
    }
    if (lam.contains("colour") && lam.at("colour").is_array())
        throw Error(
            "is one width per band: a model of an older shapesim-smooth (smooth its "
            "records again)",
            "", 0, "lambda.colour");
    m.lambda.colour = number(lam, "colour", "lambda.");
    if (m.lambda.colour < 0.0) throw Error("must be ≥ 0", "", 0, "lambda.colour");
    if (doc.contains("colours")) read_colour_population(m, doc.at("colours"));
}

// One of "points" (`where`: "points[i]."), checked against the model's n_max and bands.
MorphologyPoint read_point(const Json& pj, const std::string& where, const Morphology& m) {
    MorphologyPoint p;
    if (!pj.is_object() || !pj.contains("id") || !pj.at("id").is_string())
        throw Error("missing or not a string", "", 0, where + "id");
    p.id = pj.at("id").get<std::string>();
    p.n_max = int(number(pj, "n_max", where));
    if (p.n_max < 0 || p.n_max > m.n_max)
        throw Error("must be in [0, n_max of the model]", "", 0, where + "n_max");
    p.beta = number(pj, "beta", where);
    if (!(p.beta > 0.0)) throw Error("must be > 0", "", 0, where + "beta");
    p.mag = number(pj, "mag", where);
    p.weight = pj.contains("weight") ? number(pj, "weight", where) : 1.0;
    p.psf_beta = pj.contains("psf_beta") ? number(pj, "psf_beta", where) : 0.0;
    p.positivity_change =
        pj.contains("positivity_change") ? number(pj, "positivity_change", where) : 0.0;
    if (!(p.psf_beta >= 0.0)) throw Error("must be ≥ 0", "", 0, where + "psf_beta");
    if (!(p.weight >= 0.0)) throw Error("must be ≥ 0", "", 0, where + "weight");
    p.alignment.rotation = pj.contains("rotation") ? number(pj, "rotation", where) : 0.0;
    p.alignment.reflected = pj.value("reflected", false);
    if (pj.contains("shape_only")) {
        if (!pj.at("shape_only").is_boolean())
            throw Error("must be true or false", "", 0, where + "shape_only");
        p.shape_only = pj.at("shape_only").get<bool>();
        if (p.shape_only && p.weight != 0.0)
            throw Error("a shape-only point must have weight 0", "", 0, where + "weight");
    }
    if (!pj.contains("shape") || !pj.at("shape").is_array() ||
        pj.at("shape").size() != std::size_t(polar_count(p.n_max)))
        throw Error("must hold polar_count(n_max) [re, im] pairs", "", 0, where + "shape");
    p.shape = read_complex_pairs(pj.at("shape"), where + "shape");
    if (m.bands.empty()) return p;
    const Json* list = pj.contains("bands") ? &pj.at("bands") : nullptr;
    if (!list || !list->is_array() || list->size() != m.bands.size())
        throw Error("must hold one shape per band", "", 0, where + "bands");
    for (const Json& band : *list) {
        if (!band.is_array() || band.size() != p.shape.size())
            throw Error("must hold polar_count(n_max) [re, im] pairs per band", "", 0,
                        where + "bands");
        p.band_shapes.push_back(read_complex_pairs(band, where + "bands"));
    }
    return p;
}

// A source field (`where`: "source_fields[k]"); its magnitudes sorted.
SourceField read_source_field(const Json& f, const std::string& where) {
    SourceField field;
    if (!f.is_object()) throw Error("must be an object", "", 0, where);
    field.area_arcmin2 = number(f, "area_arcmin2", where + ".");
    if (!(field.area_arcmin2 > 0.0)) throw Error("must be > 0", "", 0, where + ".area_arcmin2");
    if (!f.contains("mags") || !f.at("mags").is_array())
        throw Error("must be an array of numbers", "", 0, where + ".mags");
    for (const Json& v : f.at("mags")) {
        if (!v.is_number() || !std::isfinite(v.get<double>()))
            throw Error("must be finite numbers", "", 0, where + ".mags");
        field.mags.push_back(v.get<double>());
    }
    std::sort(field.mags.begin(), field.mags.end());
    if (f.contains("image")) {
        if (!f.at("image").is_string()) throw Error("must be a string", "", 0, where + ".image");
        field.image = f.at("image").get<std::string>();
    }
    if (f.contains("completeness")) field.completeness = number(f, "completeness", where + ".");
    if (f.contains("star_mags")) {
        if (!f.at("star_mags").is_array())
            throw Error("must be an array of numbers", "", 0, where + ".star_mags");
        std::vector<double> stars;
        for (const Json& v : f.at("star_mags")) {
            if (!v.is_number() || !std::isfinite(v.get<double>()))
                throw Error("must be finite numbers", "", 0, where + ".star_mags");
            stars.push_back(v.get<double>());
        }
        std::sort(stars.begin(), stars.end());
        field.star_mags = std::move(stars);
    }
    return field;
}

// The real fields: "source_field" (one, of older models), "source_fields", "shape_fields".
void read_fields(const Json& doc, Morphology& m) {
    if (doc.contains("source_field"))
        m.source_fields.push_back(read_source_field(doc.at("source_field"), "source_field"));
    if (doc.contains("source_fields")) {
        if (!doc.at("source_fields").is_array())
            throw Error("must be an array", "", 0, "source_fields");
        std::size_t k = 0;
        for (const Json& f : doc.at("source_fields"))
            m.source_fields.push_back(
                read_source_field(f, "source_fields[" + std::to_string(k++) + "]"));
    }
    if (doc.contains("shape_fields")) {
        const Json& f = doc.at("shape_fields");
        if (!f.is_array()) throw Error("must be an array of strings", "", 0, "shape_fields");
        for (const Json& image : f) {
            if (!image.is_string())
                throw Error("must be an array of strings", "", 0, "shape_fields");
            m.shape_fields.push_back(image.get<std::string>());
        }
    }
}

}  // namespace

Morphology Morphology::from_json(const Json& doc) {
    if (!doc.is_object() || !doc.contains("schema") || doc.at("schema") != schema)
        throw Error(std::string("not a morphology model (expected schema \"") + schema + "\")", "",
                    0, "schema");
    Morphology m;
    // Checked as a number before it becomes an int (1e13 or NaN would not fit one).
    const double n_max = number(doc, "n_max", "");
    if (!(n_max > -1.0 && n_max < 101.0)) throw Error("must be in [0, 100]", "", 0, "n_max");
    m.n_max = int(n_max);
    if (doc.contains("zero_point") && !doc.at("zero_point").is_null())
        m.zero_point = number(doc, "zero_point", "");
    if (doc.contains("frame")) {
        if (!doc.at("frame").is_string() ||
            (doc.at("frame") != "observed" && doc.at("frame") != "intrinsic"))
            throw Error("must be \"observed\" or \"intrinsic\"", "", 0, "frame");
        m.frame = doc.at("frame").get<std::string>();
    }
    read_lambda(doc, m);
    if (doc.contains("bands")) read_bands(doc, m);
    if (!doc.contains("points") || !doc.at("points").is_array() || doc.at("points").empty())
        throw Error("must be a non-empty array", "", 0, "points");
    std::size_t i = 0;
    for (const Json& pj : doc.at("points"))
        m.points.push_back(read_point(pj, "points[" + std::to_string(i++) + "].", m));
    read_fields(doc, m);
    if (doc.contains("provenance")) m.provenance = doc.at("provenance");
    m.prepare();
    return m;
}

Morphology Morphology::read(const std::string& path) {
    std::ifstream file;
    std::istream* in = &std::cin;
    if (path != "-") {
        file.open(path);
        if (!file) throw Error("cannot open", path);
        in = &file;
    }
    std::stringstream text;
    text << in->rdbuf();
    const Json doc = parse_json_document(text.str(), path);
    try {
        return from_json(doc);
    } catch (const Error& e) {
        throw e.at(path, 0);
    }
}

}  // namespace shapesim
