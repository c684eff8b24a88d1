// shapesim-smooth: shapelet records (shapesim-decompose) → the morphology model, one JSON
// document (paper §3–4.1; DESIGN §4). The work is in the library: morphology.hpp.
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "smooth/source_fields.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/records.hpp"

#include <algorithm>
#include <vector>

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
    std::string input = "-", require,
                reject = "edge,bright_star,saturated,noise,bad_fit,holes,unsupported", weight_field;
    double beta = 0.0, mag = 0.0, modulus = 0.0, mag_limit = 0.0, area = 0.0, pixel_scale = 0.0;
    SmoothOptions smooth;  // k, lambda-phase, lambda-colour, delta, keep-colour-noise
    bool weight_left_out = false;  // RecordSelection::weight_left_out
    std::vector<std::string> fields, stars;
};

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-smooth", "[OPTION]... [FILE]", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::like |
                                    app::Common::print_params);
    Settings s;
    using app::in_range;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "shapelet records, or the first argument (default: stdin)")
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
        ("stars", po::value(&s.stars)->value_name("[IMAGE=]FILE")->composing(),
         "the field's stars (shapesim-detect --stars records; IMAGE= names a --field): their "
         "counts go into the model, and shapesim-sample draws them by default")
        ("weight-field", po::value(&s.weight_field)->value_name("NAME"),
         "parent-selection weight from this numeric record field (default: all 1)");
    options.group("Smoothing").add_options()
        ("lambda-factor", po::value(&s.smooth.k)->value_name("K")->default_value(4.0)
             ->notifier(in_range("lambda-factor", 0.0, 1e6)),
         "every lambda = K x the mean nearest-neighbour separation along its axis (paper: k)")
        ("lambda-phase", po::value(&s.smooth.phase_deg)->default_value(15.0)
             ->notifier(in_range("lambda-phase", 0.0, 180.0)), "phase smoothing length, degrees")
        ("lambda-beta", po::value(&s.beta)->value_name("ARCSEC")
             ->notifier(in_range("lambda-beta", 0.0, 1e6)), "override lambda of beta")
        ("lambda-mag", po::value(&s.mag)->notifier(in_range("lambda-mag", 0.0, 1e6)),
         "override lambda of the magnitude")
        ("lambda-colour", po::value(&s.smooth.colour)->value_name("H")->default_value(0.25, "0.25")
             ->notifier(in_range("lambda-colour", 0.0, 1e6)),
         "several bands: the colour kernel's width, in units of the population's spread "
         "(0: the parents' colours)")
        ("lambda-modulus", po::value(&s.modulus)->notifier(in_range("lambda-modulus", 0.0, 1e6)),
         "override lambda of every coefficient axis (|a_nm/a_00|, a_n0/a_00)")
        ("delta", po::bool_switch(&s.smooth.delta), "every lambda = 0: the delta-function PDF")
        ("keep-negative", po::bool_switch(&s.smooth.keep_negative),
         "keep each shape as fitted, light below zero and all (by default each is moved to the "
         "nearest shape whose light is nowhere negative; --delta keeps them always)")
        ("weight-left-out", po::bool_switch(&s.weight_left_out),
         "with a field (--like, --area, --field): each kept galaxy also stands for the field's "
         "galaxies left out in its 0.5-mag bin, so the paper's draw gives the field's magnitudes "
         "(fewer parents carry more of the draws)")
        ("keep-colour-noise", po::bool_switch(&s.smooth.keep_colour_noise),
         "several bands: keep each parent's flux ratios as measured, noise and all (by default "
         "they are deconvolved from it, so a simulation does not carry its noise twice)");
    options.positional("input", 1);
    options.alias("k", "lambda-factor");
    if (!options.parse(argc, argv)) return 0;
    AtomicTextFile file(options.common().output_or_stdout());
    const app::Log log("shapesim-smooth", options.common().verbosity);

    SmoothOptions& smooth = s.smooth;
    if (options.given("lambda-beta")) smooth.beta = s.beta;
    if (options.given("lambda-mag")) smooth.mag = s.mag;
    if (options.given("lambda-modulus")) smooth.modulus = s.modulus;
    smooth.validate();
    RecordSelection selection{app::split_list(s.require), app::split_list(s.reject), {}, {},
                              s.weight_field, s.weight_left_out};
    if (options.given("mag-limit")) selection.mag_limit = s.mag_limit;

    app::SourceFields fields = app::read_source_fields(
        options.common().like, options.given("area") ? std::optional(s.area) : std::nullopt,
        options.given("pixel-scale") ? std::optional(s.pixel_scale) : std::nullopt, s.fields);
    app::add_field_stars(fields, s.stars);
    if (!s.fields.empty()) selection.images = fields.images();
    JsonlReader reader(s.input, {ShapeletRecord::schema});
    SelectedRecords selected = select_records(reader, selection, fields.counted);
    if (selected.kept.empty())
        throw Error("no record left to smooth (" + std::to_string(selected.read) +
                    " read; see --require, --reject, --mag-limit)", reader.name());
    Morphology morphology = build_morphology(selected.kept, smooth);
    fields.complete();
    weight_by_counted_area(fields.counted, selected.kept, selected.field, selected.weights);
    if (selection.weight_left_out)
        weight_by_kept_fraction(fields.counted, selected.kept, selected.field, selected.weights);
    const long shape_only =
        mark_point_fields(morphology, selected, selection, fields.counted.size());
    if (shape_only > 0 && shape_only == long(selected.kept.size()))
        throw Error("every kept record comes from a shape-only field: nothing to count",
                    reader.name());
    for (std::size_t k = 0; k < fields.counted.size() && !s.fields.empty(); ++k)
        log.verbose("field ", fields.counted[k].image, ": ", fields.counted[k].area_arcmin2,
                    " arcmin^2, ", fields.counted[k].mags.size(), " galaxies, complete to ",
                    fields.counted[k].completeness);
    if (!fields.shape_images.empty())
        log.verbose(shape_only, " shape-only models from ", fields.shape_images.size(),
                    " field(s)");
    for (const SourceField& f : fields.counted)
        if (f.star_mags)
            log.info(f.star_mags->size(), " stars in ", f.image.empty() ? "the field" : f.image,
                     " (", f.area_arcmin2, " arcmin^2): shapesim-sample draws their counts");
    morphology.source_fields = std::move(fields.counted);
    morphology.shape_fields = fields.shape_images;
    morphology.provenance = smooth_provenance(reader.name(), selected, selection, smooth);
    file.stream() << morphology.to_json().dump() << '\n';
    file.commit();
    log.info(selected.kept.size(), " of ", selected.read, " models kept (n_max up to ",
             morphology.n_max, "); lambda: beta ", morphology.lambda.beta, "\", mag ",
             morphology.lambda.mag, ", phase ", morphology.lambda.phase_deg, " deg");
    for (const auto& [why, n] : selected.dropped) log.verbose(n, " dropped: ", why);
    std::vector<double> moved;
    for (const MorphologyPoint& p : morphology.points)
        if (p.positivity_change > 0.0) moved.push_back(p.positivity_change);
    if (!moved.empty()) {
        std::sort(moved.begin(), moved.end());
        log.verbose(moved.size(), " shapes moved to their nearest non-negative shape (change ",
                    "|c'-c|/|c| median ", moved[moved.size() / 2], ", largest ", moved.back(), ")");
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-smooth", run); }
