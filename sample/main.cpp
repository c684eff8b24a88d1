// shapesim-sample: the morphology model (shapesim-smooth) → new objects over a sky field as
// shapesim.object/1 records on stdout (paper §4.1–4.2; DESIGN §4, §6). The work is in the
// library: morphology.hpp (the draws), sample.hpp (the field, stars, tiles).
#include "app/field_options.hpp"
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/sample.hpp"

#include <fstream>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Draw new galaxies from the morphology model: each a magnitude from the published galaxy\n"
    "counts (--counts), a shape parent among the --neighbours real galaxies\n"
    "nearest that magnitude, mixed with the --mix - 1 galaxies of its window most alike to it\n"
    "(random weights: a new galaxy whose light is nowhere negative), then a uniform position,\n"
    "orientation and flip; add stars; write shapesim.object/1 records. --neighbours 0 is the\n"
    "paper's draw (Silverman's bootstrap: one real galaxy, every parameter perturbed by an\n"
    "Epanechnikov kernel). Every draw comes from the stream of (seed, object), so a tile\n"
    "(--tile) holds exactly the objects of the whole field that reach it.\n"
    "\n"
    "Examples:\n"
    "  shapesim-sample morphology.pdf.json --like hdf.fits --seed 7 > objects.jsonl\n"
    "  shapesim-sample morphology.pdf.json --area 6 --seed 7 > objects6.jsonl   # 6 arcmin^2\n"
    "  shapesim-sample morphology.pdf.json --like hdf.fits --tile 1 1 256 256 > tile.jsonl\n"
    "  shapesim-sample --area 6 --tile-grid 1024   # the tiles: 'IX IY X0 Y0 X1 Y1' lines\n"
    "  shapesim-sample --replay shapelets.jsonl --like hdf.fits > replay.jsonl   # the real\n"
    "      galaxies where they were fitted: render and measure it beside the real image";

struct Settings {
    std::string model;
    bool replay = false;
    app::FieldOptions field;
    double margin = 0.5;
    std::string star_histogram, counts = "law";
    std::uint64_t count = 0, star_count = 0;
    std::vector<long> tile_grid;
    SampleOptions sample;
};

// --replay: the fits of the field's own galaxies, where they were fitted. The draw's options
// have no meaning here: any given is refused rather than ignored.
int replay(const app::ProgramOptions& options, const Settings& s, const FieldGeometry& field,
           const std::optional<Tile>& tile, AtomicTextFile& file, const app::Log& log) {
    for (const char* name : {"density", "count", "ring", "mag-limit", "faint-limit", "zero-point",
                             "neighbours", "mix", "max-mag-shift", "counts", "size-slope",
                             "max-perturbation", "hole-allowance", "star-density", "star-count",
                             "star-histogram", "star-mag-min", "star-mag-max", "star-slope"})
        if (options.given(name))
            throw po::error(std::string("--") + name + ": not with --replay (it draws nothing)");
    JsonlReader reader(s.model, {ShapeletRecord::schema});
    std::vector<long> lines;
    const std::vector<ShapeletRecord> fits = reader.read_all<ShapeletRecord>(1, &lines);
    JsonlWriter out(file.stream(), file.name());
    ReplaySummary summary;
    try {
        summary = replay_field(fits, field, s.margin / field.pixel_scale, tile,
                               [&](const ObjectRecord& r) { out.write(r.to_json()); });
    } catch (const Error& e) {  // its line is the fit's place in `fits`: the file's line here
        throw e.at(reader.name(), e.line() > 0 ? lines[std::size_t(e.line() - 1)] : 0);
    }
    file.commit();
    log.info(summary.written, " of ", fits.size(), " fits replayed where they were fitted (",
             summary.stars, " stars, ", summary.no_light, " with no light to draw",
             tile ? ", " + std::to_string(summary.outside_tile) + " outside the tile" : "",
             ") in ", log.elapsed(), " s");
    return 0;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-sample", "[OPTION]... MODEL", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::seed | app::Common::like | app::Common::config |
                                    app::Common::print_params);
    Settings s;
    SampleOptions& o = s.sample;
    using app::in_range;
    options.group("Input").add_options()(
        "input,i", po::value(&s.model)->value_name("MODEL"),
        "the morphology model (shapesim-smooth), or the first argument");
    options.positional("input", 1);
    options.group("Input").add_options()(
        "replay", po::bool_switch(&s.replay),
        "the input is shapesim-decompose's galaxy models of the --like image: write each where\n"
        "it was fitted, as fitted (no draw, no stars), to render with new noise and measure\n"
        "beside the real image (shapesim-measure --compare-paired)");
    s.field.declare(options, "Field (default: --like)",
                    "only the objects reaching these field pixels (FITS, inclusive)");
    options.group("Field (default: --like)").add_options()
        ("tile-grid", po::value(&s.tile_grid)->value_name("W [H]")->multitoken(),
         "print the field's grid of W x H pixel tiles, one 'IX IY X0 Y0 X1 Y1' line each (the\n"
         "--tile arguments; IX, IY from 0), and exit; no MODEL needed")
        ("margin", po::value(&s.margin)->default_value(0.5)
             ->notifier(in_range("margin", 0.0, 3600.0)),
         "arcsec added to every object's reach for the tile test (PSF wings)")
        ("cell", po::value(&o.cell)->default_value(4096)
             ->notifier(in_range<long>("cell", 1, 1L << 30)),
         "sky cells of this many pixels a side key the draws: a tile reads only the cells it\n"
         "reaches (a field of one cell draws as before cells; another size, another sky)");
    options.group("Galaxies").add_options()
        ("density", po::value(&o.density)->default_value(700.0)
             ->notifier(in_range("density", 0.0, 1e8)),
         "galaxies per arcmin^2 (Poisson; default: the model's real field, else 700)")
        ("count", po::value(&s.count), "exactly this many galaxies instead")
        ("ring", po::value(&o.ring)->value_name("N")->default_value(1)
             ->notifier(in_range("ring", 1, 1000)),
         "shape-noise cancellation: galaxies in rings of N copies of one draw, copy m turned by "
         "m x 180/N degrees (2: rotated pairs), each at its own position; their ellipticities "
         "sum to zero (with --count: a multiple of N)")
        ("mag-limit", po::value(&o.mag_limit)->default_value(29.0)
             ->notifier(in_range("mag-limit", -100.0, 100.0)), "nothing fainter")
        ("faint-limit", po::value<double>()->notifier([&o](double m) { o.faint_limit = m; })
             ->value_name("MAG"),
         "also galaxies fainter than --mag-limit down to MAG, from the fitted counts "
         "extrapolated: the sky's unresolved light (ids u<k>, \"below_limit\": true)")
        ("zero-point", po::value(&o.zero_point)->notifier(in_range("zero-point", -100.0, 100.0)),
         "of the output fluxes (default: the model's)")
        ("neighbours", po::value(&o.draw.neighbours)->default_value(16)
             ->notifier(in_range("neighbours", 0, 1000000)),
         "take each galaxy's shape from one of this many real galaxies nearest to its drawn "
         "magnitude (no clones at the bright end); 0: the paper's draw, shape and magnitude of "
         "one parent")
        ("mix", po::value(&o.draw.mix)->default_value(3)->notifier(in_range("mix", 0, 64)),
         "each --neighbours galaxy a mixture of this many real galaxies near its magnitude and "
         "shape, weighted at random (new galaxies that do not ring; at most --neighbours); "
         "0 or 1: one galaxy, perturbed")
        ("max-mag-shift", po::value(&o.draw.max_mag_shift)->default_value(2.0)
             ->notifier(in_range("max-mag-shift", 0.0, 100.0)),
         "--neighbours only within this many magnitudes of the draw (the nearest always)")
        ("counts", po::value(&s.counts)->default_value("law")->value_name("law|FILE|fit|parents"),
         "--neighbours draws' magnitudes (and the density with them): 'law', the published\n"
         "I-band (F814W) galaxy counts, the same at every --mag-limit (COSMOS2020, HDF-N\n"
         "fainter; docs/sample.md); FILE, a law of lines 'mag log10(dN/dm per deg^2 per mag)';\n"
         "'fit', a power law fitted to the model's fields up to --mag-limit; 'parents', a\n"
         "parent's magnitude perturbed")
        ("size-slope", po::value(&o.draw.size_slope)->default_value(0.3)
             ->notifier(in_range("size-slope", -5.0, 5.0)),
         "a shape moved to another magnitude has its beta scaled as L^this")
        ("max-perturbation", po::value(&o.draw.max_perturbation)->default_value(0.5)
             ->notifier(in_range("max-perturbation", 1e-6, 1e6)),
         "redraw perturbations changing the shape by more than this fraction, |c'-c|/|c|")
        ("hole-allowance", po::value(&o.draw.hole_allowance)->default_value(0.01)
             ->notifier(in_range("hole-allowance", 0.0, 1e6)),
         "redraw perturbations whose model dips below zero deeper than the real galaxy's by "
         "more than this fraction of the peak");
    app::declare_star_options(options, o.stars, s.star_count, s.star_histogram);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-sample", options.common().verbosity);

    const FieldGeometry field = s.field.field(options);
    AtomicTextFile file(options.common().output_or_stdout());
    if (options.given("tile-grid")) {
        if (s.tile_grid.empty() || s.tile_grid.size() > 2 || s.tile_grid.front() < 1 ||
            s.tile_grid.back() < 1)
            throw po::error("--tile-grid takes W [H], whole numbers of pixels >= 1");
        write_tile_grid(file.stream(), file.name(), field.nx, field.ny, s.tile_grid.front(),
                        s.tile_grid.back());
        file.commit();
        return 0;
    }
    if (s.model.empty())
        throw po::error(s.replay ? "give the models to replay (shapesim-decompose's records)"
                                 : "give the morphology MODEL (from shapesim-smooth)");
    const std::optional<Tile> tile = s.field.window(options, field, false);
    if (s.replay) return replay(options, s, field, tile, file, log);

    const Morphology morphology = Morphology::read(s.model);
    if (!options.given("zero-point")) {
        if (!morphology.zero_point)
            throw po::error("the model has no zero point: give --zero-point");
        o.zero_point = *morphology.zero_point;
    }
    // The counts: a law (shipped or a file's), fitted to the model's fields, or the parents'.
    if (s.counts != "law" && s.counts != "fit" && s.counts != "parents" &&
        !std::ifstream(s.counts).good())
        throw po::error("--counts takes law, fit, parents or a count-law file; '" + s.counts +
                        "' is none (no such file)");
    const CountSource source = s.counts == "fit"       ? CountSource::fit
                               : s.counts == "parents" ? CountSource::parents
                                                       : CountSource::law;
    const bool law_file = source == CountSource::law && s.counts != "law";
    const CountModel law = law_file ? read_count_law(s.counts) : count_law();
    if (!options.given("mix")) o.draw.mix = std::min(o.draw.mix, o.draw.neighbours);
    apply_model_counts(o, morphology, source, options.given("density"), s.model, law);
    if (const std::optional<CountModel>& counts = o.draw.counts; counts && counts->tabulated())
        log.info("galaxy counts: ", counts->density(), " per arcmin^2 over ", counts->bright,
                 " - ", counts->faint, ", ", counts->source);
    else if (counts)
        log.info("galaxy counts: d log10 N / dm = ", counts->slope, ", ", counts->density(),
                 " per arcmin^2 over ", counts->bright, " - ", counts->faint, ", fitted to ",
                 counts->galaxies, " galaxies of ", morphology.source_fields.size(), " field(s)");
    o.seed = options.common().seed;
    if (options.given("count")) o.count = s.count;
    if (options.given("star-count")) o.star_count = s.star_count;
    if (!options.given("star-mag-max")) o.stars.mag_max = o.mag_limit;
    if (!s.star_histogram.empty()) o.stars.bins = read_star_histogram(s.star_histogram);
    // The real fields' stars (smooth --stars) unless the stars are given here.
    const bool stars_given = options.given("star-density") || options.given("star-count") ||
                             !s.star_histogram.empty();
    if (const auto field_stars = field_star_counts(morphology.source_fields, o.mag_limit);
        field_stars && !stars_given) {
        o.stars = *field_stars;
        log.info("stars: ", o.stars.density, " per arcmin^2 to magnitude ", o.mag_limit,
                 ", the model's fields' counts (--star-density 0: none)");
    }
    o.margin = s.margin / field.pixel_scale;

    const long shape_only = count_shape_only(morphology);
    if (shape_only > 0 && o.draw.neighbours == 0)
        log.info(shape_only,
                 " shape-only models unused: only --neighbours draws take their shapes");
    JsonlWriter out(file.stream(), file.name());
    ParentShares parents;
    const SampleSummary summary =
        sample_field(morphology, field, o, tile, [&](const ObjectRecord& r) {
            out.write(r.to_json());
            parents.add(r);
        });
    file.commit();
    log.info(summary.describe(field, o.density, tile.has_value()), log.elapsed(), " s");
    log.info("largest share of one parent among the galaxies written: ", parents.summary());
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-sample", run); }
