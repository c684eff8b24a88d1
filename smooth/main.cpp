// shapesim-smooth: shapelet records (shapesim-decompose) → the morphology model, one JSON
// document (paper §3–4.1; DESIGN §4). The work is in the library: morphology.hpp.
#include "shapesim/app/options.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/records.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/version.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Align the shapelet models (rotate the ellipticity onto x, flip so the a_42 phase is\n"
    "positive), place them in the parameter space of a_nm/a_00 moduli and phases, beta and\n"
    "magnitude, compute the smoothing length of every axis (k x the mean nearest-neighbour\n"
    "separation; 15 degrees for phases) and write the morphology model that\n"
    "shapesim-sample draws from, as one JSON document on stdout.\n"
    "\n"
    "Example:\n"
    "  shapesim-smooth < shapelets.jsonl > morphology.pdf.json\n"
    "  shapesim-smooth --delta < shapelets.jsonl > delta.pdf.json   # the delta-function PDF\n"
    "  shapesim-smooth --like hdf.fits < shapelets.jsonl > morphology.pdf.json   # + its density\n"
    "\n"
    "With --like (or --area), the model also records the real field's area and every input\n"
    "galaxy's magnitude, kept or not, and shapesim-sample then draws the real galaxy density.";

struct Settings {
    // Every fit that is a faithful model: whatever stopped its order search (converged,
    // flattened at the noise, the cap, the stamp), unless χ²_r says it misses real structure
    // ("bad_fit"), rings ("holes") or lies off its data ("unsupported"). The paper's
    // `converged|n_max_cap` is one --require away.
    std::string input = "-", require, reject = "edge,bright_star,noise,bad_fit,holes,unsupported",
                weight_field;
    double k = 4.0, phase = 15.0, beta = 0.0, mag = 0.0, modulus = 0.0, mag_limit = 0.0, area = 0.0,
           pixel_scale = 0.0;
    bool delta = false;
    bool keep_colour_noise = false;
    double colour = 0.25;
    std::vector<std::string> fields;
};

bool has(const std::vector<std::string>& flags, const std::string& flag) {
    return std::find(flags.begin(), flags.end(), flag) != flags.end();
}

// Whether `flags` holds one of the '|'-separated alternatives of `wanted`.
bool has_any(const std::vector<std::string>& flags, const std::string& wanted) {
    for (std::size_t start = 0;;) {
        const std::size_t bar = wanted.find('|', start);
        if (has(flags, wanted.substr(start, bar - start))) return true;
        if (bar == std::string::npos) return false;
        start = bar + 1;
    }
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-smooth", "[OPTION]...", description,
                                app::Common::quiet | app::Common::verbose | app::Common::config |
                                    app::Common::like | app::Common::print_params);
    Settings s;
    using app::in_range;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "shapelet records (default: stdin)")
        ("require", po::value(&s.require)->value_name("FLAGS")->default_value(""),
         "keep records carrying all these flags (comma-separated; empty: all; A|B: either);\n"
         "the paper's selection: converged|n_max_cap")
        ("reject", po::value(&s.reject)->value_name("FLAGS")
             ->default_value(s.reject),
         "drop records carrying any of these flags (bad_fit: chi2_r above "
         "shapesim-decompose --bad-fit-chi2r; holes: dips below zero beyond its --max-hole; "
         "unsupported: light off the data beyond its --max-unsupported)")
        ("mag-limit", po::value(&s.mag_limit)->value_name("MAG"),
         "drop records fainter than this")
        ("area", po::value(&s.area)->value_name("ARCMIN2")->notifier(in_range("area", 1e-9, 1e9)),
         "area of the real field the records come from (or --like its image)")
        ("pixel-scale", po::value(&s.pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("pixel-scale", 1e-6, 3600.0)),
         "arcsec per pixel of a --like image whose header has no WCS")
        ("field", po::value(&s.fields)->value_name("IMAGE=ARCMIN2[@MAG]")->composing(),
         "one of several real fields the records come from (their \"image\"), its area and "
         "the magnitude its counts are complete to (default: their turnover); repeat for "
         "each: the counts are combined field by field where complete, and each galaxy "
         "weighted so the drawn magnitudes follow them; IMAGE=shapes: a shape-only field "
         "(isolated-galaxy cutouts): its galaxies join the PDF and shape the draws near "
         "their magnitude (shapesim-sample --neighbours) but add nothing to the counts")
        ("weight-field", po::value(&s.weight_field)->value_name("NAME"),
         "parent-selection weight from this numeric record field (default: all 1)");
    options.group("Smoothing").add_options()
        ("k", po::value(&s.k)->default_value(4.0)->notifier(in_range("k", 0.0, 1e6)),
         "lambda = k x the mean nearest-neighbour separation along each axis")
        ("lambda-phase", po::value(&s.phase)->default_value(15.0)
             ->notifier(in_range("lambda-phase", 0.0, 180.0)), "phase smoothing length, degrees")
        ("lambda-beta", po::value(&s.beta)->value_name("ARCSEC")
             ->notifier(in_range("lambda-beta", 0.0, 1e6)), "override lambda of beta")
        ("lambda-mag", po::value(&s.mag)->notifier(in_range("lambda-mag", 0.0, 1e6)),
         "override lambda of the magnitude")
        ("lambda-colour", po::value(&s.colour)->value_name("H")->default_value(0.25, "0.25")
             ->notifier(in_range("lambda-colour", 0.0, 1e6)),
         "several bands: the colour kernel's width, in units of the population's spread "
         "(0: the parents' colours)")
        ("lambda-modulus", po::value(&s.modulus)->notifier(in_range("lambda-modulus", 0.0, 1e6)),
         "override lambda of every coefficient axis (|a_nm/a_00|, a_n0/a_00)")
        ("delta", po::bool_switch(&s.delta), "every lambda = 0: the delta-function PDF")
        ("keep-colour-noise", po::bool_switch(&s.keep_colour_noise),
         "several bands: keep each parent's flux ratios as measured, noise and all (by default "
         "they are deconvolved from it, so a simulation does not carry its noise twice)");
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-smooth", options.common().verbosity);

    SmoothOptions smooth;
    smooth.k = s.k;
    smooth.phase_deg = s.phase;
    smooth.delta = s.delta;
    smooth.keep_colour_noise = s.keep_colour_noise;
    if (options.given("lambda-beta")) smooth.beta = s.beta;
    if (options.given("lambda-mag")) smooth.mag = s.mag;
    if (options.given("lambda-modulus")) smooth.modulus = s.modulus;
    smooth.colour = s.colour;
    smooth.validate();
    const std::vector<std::string> required = app::split_list(s.require),
                                   rejected = app::split_list(s.reject);

    std::vector<SourceField> fields;
    if (int(!options.common().like.empty()) + int(options.given("area")) + int(!s.fields.empty()) > 1)
        throw po::error("give one of --like, --area and --field");
    if (!options.common().like.empty())
        fields.push_back(SourceField{"",
                                     read_field_geometry(options.common().like,
                                                         options.given("pixel-scale")
                                                             ? std::optional(s.pixel_scale)
                                                             : std::nullopt)
                                         .area_arcmin2(),
                                     {}});
    else if (options.given("area"))
        fields.push_back(SourceField{"", s.area, {}});
    std::vector<bool> completeness_given;
    std::vector<std::string> shape_images;  // shape-only fields
    for (const std::string& text : s.fields) {
        const std::size_t eq = text.rfind('=');
        if (eq == std::string::npos || eq == 0)
            throw po::error("--field wants IMAGE=ARCMIN2[@MAG] or IMAGE=shapes, got '" + text + "'");
        const auto known = [&](const std::string& image) {
            return std::find(shape_images.begin(), shape_images.end(), image) != shape_images.end() ||
                   std::any_of(fields.begin(), fields.end(),
                               [&](const SourceField& g) { return g.image == image; });
        };
        if (text.substr(eq + 1) == "shapes") {
            if (known(text.substr(0, eq))) throw po::error("--field " + text.substr(0, eq) + " given twice");
            shape_images.push_back(text.substr(0, eq));
            continue;
        }
        SourceField f;
        f.image = text.substr(0, eq);
        const std::string rest = text.substr(eq + 1);
        const std::size_t at = rest.find('@');
        try {
            std::size_t used = 0;
            f.area_arcmin2 = std::stod(rest.substr(0, at), &used);
            if (used != rest.substr(0, at).size()) throw std::invalid_argument("trailing");
            if (at != std::string::npos) {
                f.completeness = std::stod(rest.substr(at + 1), &used);
                if (used != rest.size() - at - 1) throw std::invalid_argument("trailing");
            }
        } catch (const std::exception&) {
            throw po::error("--field wants IMAGE=ARCMIN2[@MAG] or IMAGE=shapes, got '" + text + "'");
        }
        if (!(f.area_arcmin2 > 0.0) || !(std::isfinite(f.area_arcmin2)) ||
            (at != std::string::npos && !std::isfinite(f.completeness)))
            throw po::error("--field " + text + ": the area must be > 0, the magnitude finite");
        if (known(f.image)) throw po::error("--field " + f.image + " given twice");
        completeness_given.push_back(at != std::string::npos);
        fields.push_back(std::move(f));
    }
    if (!s.fields.empty() && fields.empty())
        throw po::error("--field: at least one field must give its area (only shape-only fields given)");
    // Every --field image: the counted fields', then the shape-only ones.
    std::vector<std::string> images;
    for (const SourceField& f : fields) images.push_back(f.image);
    images.insert(images.end(), shape_images.begin(), shape_images.end());
    std::vector<std::size_t> kept_field;  // each kept record's index in `images` (≥ fields.size(): shape-only)

    JsonlReader reader(s.input, {ShapeletRecord::schema});
    std::vector<ShapeletRecord> kept;
    std::vector<double> weights;
    std::map<std::string, long> dropped;
    std::uint64_t hash = fnv1a_64("");
    Json record;
    long read = 0;
    while (reader.next(record)) {
        ++read;
        ShapeletRecord r;
        try {
            r = ShapeletRecord::from_json(record);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
        // The input's identity for the provenance: FNV-1a over the records' compact dumps.
        hash ^= fnv1a_64(record.dump());
        hash *= 0x100000001b3ULL;
        std::size_t field = 0;
        if (!s.fields.empty()) {
            const std::string image = record.value("image", std::string());
            field = std::size_t(std::find(images.begin(), images.end(), image) - images.begin());
            if (field == images.size())
                throw reader.locate(Error("record " + r.id + " comes from '" + image +
                                              "', none of the --field images", "", 0, "image"));
        }
        if (field < fields.size() && r.mag && record.value("kind", std::string("galaxy")) != "star")
            fields[field].mags.push_back(*r.mag);
        // Counted under the first reason, in the order the options list them.
        std::string why;
        for (const auto& f : required)
            if (why.empty() && !has_any(r.flags, f)) why = "not " + f;
        for (const auto& f : rejected)
            if (why.empty() && has(r.flags, f)) why = f;
        if (why.empty() && !r.mag) why = "no magnitude";
        if (why.empty() && options.given("mag-limit") && *r.mag > s.mag_limit) why = "fainter than --mag-limit";
        if (why.empty() && !(r.coeffs[0].real() > 0.0)) why = "a_00 <= 0";
        if (!why.empty()) {
            ++dropped[why];
            continue;
        }
        double weight = 1.0;
        if (!s.weight_field.empty()) {
            try {
                const auto w = optional_double(r.extra, s.weight_field);
                if (!w || !(*w >= 0.0))
                    throw Error("missing, or not a number ≥ 0", "", 0, s.weight_field);
                weight = *w;
            } catch (const Error& e) {
                throw reader.locate(e);
            }
        }
        kept.push_back(std::move(r));
        weights.push_back(weight);
        kept_field.push_back(field);
    }
    if (kept.empty())
        throw Error("no record left to smooth (" + std::to_string(read) +
                    " read; see --require, --reject, --mag-limit)", reader.name());
    Morphology morphology = build_morphology(kept, smooth);
    for (SourceField& f : fields) std::sort(f.mags.begin(), f.mags.end());
    for (std::size_t k = 0; k < completeness_given.size(); ++k)
        if (!completeness_given[k]) fields[k].completeness = count_turnover(fields[k].mags);
    // Several fields: each galaxy stands for 1/(area counted at its magnitude) galaxies per
    // arcmin², none where its own field is not counted (fainter than its completeness).
    if (fields.size() > 1)
        for (std::size_t i = 0; i < weights.size(); ++i) {
            if (kept_field[i] >= fields.size()) continue;  // shape-only
            const auto counted = fields_counted(fields, *kept[i].mag);
            double area = 0.0;
            bool mine = false;
            for (std::size_t k : counted) {
                area += fields[k].area_arcmin2;
                mine = mine || k == kept_field[i];
            }
            weights[i] = mine ? weights[i] / area : 0.0;
        }
    // Ids are per image: with several, each point's id gets its image's short name
    // ("hdfn_f814w_v2:117", "AEGIS_F814w_images_01[1]:6"; the whole name where two clash), so
    // a simulation's `parent` names one real galaxy.
    if (images.size() > 1) {
        std::vector<std::string> labels;
        for (const std::string& image : images) {
            std::string label = image.substr(image.find_last_of('/') + 1);
            const std::size_t fits = label.find(".fits");
            if (fits != std::string::npos) label.erase(fits, 5);
            labels.push_back(label);
        }
        for (std::size_t k = 0; k < labels.size(); ++k)
            if (std::count(labels.begin(), labels.end(), labels[k]) > 1) labels[k] = images[k];
        for (std::size_t i = 0; i < kept.size(); ++i)
            morphology.points[i].id = labels[kept_field[i]] + ":" + morphology.points[i].id;
    }
    long shape_only = 0;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        morphology.points[i].shape_only = !s.fields.empty() && kept_field[i] >= fields.size();
        morphology.points[i].weight = morphology.points[i].shape_only ? 0.0 : weights[i];
        shape_only += morphology.points[i].shape_only;
    }
    if (shape_only > 0 && shape_only == long(kept.size()))
        throw Error("every kept record comes from a shape-only field: nothing to count", reader.name());
    for (std::size_t k = 0; k < fields.size() && !s.fields.empty(); ++k)
        log.verbose("field ", fields[k].image, ": ", fields[k].area_arcmin2, " arcmin^2, ",
                    fields[k].mags.size(), " galaxies, complete to ", fields[k].completeness);
    if (!shape_images.empty())
        log.verbose(shape_only, " shape-only models from ", shape_images.size(), " field(s)");
    morphology.source_fields = std::move(fields);
    morphology.shape_fields = shape_images;
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
    Json dropped_json = Json::object();
    for (const auto& [why, n] : dropped) dropped_json[why] = n;
    morphology.provenance = {{"program", "shapesim-smooth"},
                             {"version", version()},
                             {"input", reader.name()},
                             {"input_records", read},
                             {"input_fnv1a64", hex},
                             {"dropped", dropped_json},
                             {"options",
                              {{"k", s.k},
                               {"lambda_phase", s.phase},
                               {"delta", s.delta},
                               {"keep_colour_noise", s.keep_colour_noise},
                               {"lambda_colour", s.colour},
                               {"require", required},
                               {"reject", rejected}}}};
    std::cout << morphology.to_json().dump() << '\n';
    std::cout.flush();
    if (!std::cout) throw Error("cannot write the morphology model", "stdout");
    log.info(kept.size(), " of ", read, " models kept (n_max up to ", morphology.n_max,
             "); lambda: beta ", morphology.lambda.beta, "\", mag ", morphology.lambda.mag,
             ", phase ", morphology.lambda.phase_deg, " deg");
    for (const auto& [why, n] : dropped) log.verbose(n, " dropped: ", why);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-smooth", run); }
