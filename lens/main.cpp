// shapesim-lens: shapesim.object/1 records → the same records, each galaxy carrying the
// lensing it sees ("lensing": g1, g2, kappa, magnify), which shapesim-render applies in
// shapelet space before the PSF. The work is in the library: lensing.hpp.
#include "app/field_options.hpp"
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/lensing.hpp"
#include "shapesim/records.hpp"

#include <algorithm>
#include <cmath>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Give every galaxy of a catalogue (shapesim-sample) the lensing it sees at its position:\n"
    "a Gaussian random shear field of a convergence power spectrum (--power-spectrum, with an\n"
    "optional --b-power), NFW halos (--halo, Wright & Brainerd's closed form), a constant\n"
    "--shear and --kappa, or their sum. Each galaxy's record gains \"lensing\": the reduced\n"
    "shear g = gamma/(1 - kappa), kappa and whether to magnify; shapesim-render applies it\n"
    "before the PSF (flux and size magnified by mu unless --no-magnify) and its truth carries\n"
    "g1, g2, kappa, mu and the ellipticity before and after. Stars pass unlensed. A random\n"
    "field is realised over the whole field from --seed alone, so tiles of one field see the\n"
    "same shear. The copies of a ring (shapesim-sample --ring) all see their first copy's\n"
    "lensing, so their shape noise cancels. Shears are in the image's pixel frame (x right,\n"
    "y up), as render's --shear.\n"
    "\n"
    "Examples:\n"
    "  shapesim-lens --like hdf.fits --power-spectrum cosmic.txt --seed 3 < objects.jsonl \\\n"
    "      | shapesim-render --like hdf.fits --psf psf.jsonl -o lensed.fits\n"
    "  shapesim-lens --area 6 --halo 1500 1500 1e15 4 0.3 --source-z 1 < objects.jsonl\n"
    "  shapesim-lens --area 6 --shear 0.02 0 < objects.jsonl   # one shear for all";

struct Settings {
    std::string input = "-", power, b_power, map;
    long map_binning = 0;
    app::FieldOptions field;
    std::vector<double> shear, halos;
    double kappa = 0.0, source_z = 0.0;
    Cosmology cosmology;
    GaussianFieldOptions gaussian;
    bool no_magnify = false, drop_strong = false;
    WeakLensingLimits limits;
};

// κ, γ1, γ2 at the centres of B × B blocks of field pixels, as three float images with the
// field's WCS scaled to the blocks (a SIP distortion is left out of the map's).
void write_map(const std::string& path, const LensingSources& lenses, const FieldGeometry& field,
               long binning, const app::Log& log) {
    const long b = binning > 0
                       ? binning
                       : std::max(1L, (std::max(long(field.nx), long(field.ny)) + 1023) / 1024);
    const long mx = (field.nx + b - 1) / b, my = (field.ny + b - 1) / b;
    ImageArray kappa(my, mx), gamma1(my, mx), gamma2(my, mx);
    for (long j = 0; j < my; ++j)
        for (long i = 0; i < mx; ++i) {
            // Map pixel (i+1, j+1) is centred on field pixel B (i + ½) + ½.
            const Convergence c =
                lenses.at(double(b) * (double(i) + 0.5) + 0.5, double(b) * (double(j) + 0.5) + 0.5);
            kappa(j, i) = c.kappa;
            gamma1(j, i) = c.gamma1;
            gamma2(j, i) = c.gamma2;
        }
    const Wcs wcs = field.wcs.binned(int(b));
    FitsWriter out(path, "shapesim-lens");
    const std::vector<FitsKeyword> keywords{
        FitsKeyword("BINNING", double(b), "field pixels per map pixel")};
    out.write_image(kappa, FitsImageSpec{"KAPPA", -32, "", wcs, keywords, {"convergence"}});
    out.write_image(
        gamma1, FitsImageSpec{"GAMMA1", -32, "", wcs, keywords, {"shear gamma1 (image frame)"}});
    out.write_image(
        gamma2, FitsImageSpec{"GAMMA2", -32, "", wcs, keywords, {"shear gamma2 (image frame)"}});
    out.commit();
    log.verbose("map: ", mx, " x ", my, " pixels of ", b, " x ", b, " field pixels in ", path);
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-lens", "[OPTION]... [FILE]", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::like | app::Common::seed |
                                    app::Common::print_params);
    Settings s;
    using app::in_range;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "object records, or the first argument (default: stdin)");
    s.field.declare(options, "Field (the one the objects' x, y are in)", "");
    options.group("Lenses (any together: their kappa and gamma add)").add_options()
        ("power-spectrum", po::value(&s.power)->value_name("FILE"),
         "a Gaussian random field of this convergence power spectrum: lines 'ell P(ell)', ell in "
         "1/radian, P in steradian (P zero outside the table)")
        ("b-power", po::value(&s.b_power)->value_name("FILE"),
         "a B mode of this power spectrum too (a systematics test; none by default)")
        ("spacing", po::value(&s.gaussian.spacing)->value_name("ARCSEC")
             ->notifier(in_range("spacing", 1e-6, 1e7)),
         "the random field holds power at ell < pi/spacing (default: the field's "
         "longer side / 128)")
        ("padding", po::value(&s.gaussian.padding)->value_name("F")->default_value(2.0)
             ->notifier(in_range("padding", 1.0, 16.0)),
         "the random field's period over the field's size (it repeats beyond; 1: the field's)")
        ("halo", po::value(&s.halos)->value_name("X Y M200 C Z")->multitoken()->composing(),
         "an NFW halo centred at field pixel X Y, of M200 (critical) in M_sun, concentration C, "
         "redshift Z; repeat for more")
        ("source-z", po::value(&s.source_z)->value_name("Z")
             ->notifier(in_range("source-z", 1e-6, 20.0)),
         "the redshift of every lensed galaxy (needed with --halo)")
        ("h0", po::value(&s.cosmology.h0)->default_value(70.0)
             ->notifier(in_range("h0", 1.0, 1000.0)),
         "Hubble constant, km/s/Mpc (flat LCDM)")
        ("omega-m", po::value(&s.cosmology.omega_m)->default_value(0.3)
             ->notifier(in_range("omega-m", 1e-6, 1.0)),
         "matter density (Omega_Lambda = 1 - Omega_m)")
        ("shear", po::value(&s.shear)->value_name("G1 G2")->multitoken(),
         "a constant shear gamma added everywhere")
        ("kappa", po::value(&s.kappa)->notifier(in_range("kappa", -1.0, 0.999)),
         "a constant convergence added everywhere");
    options.group("Output").add_options()
        ("map", po::value(&s.map)->value_name("FITS"),
         "also write the lensing over the field: image HDUs KAPPA, GAMMA1, GAMMA2 (the field's "
         "WCS, binned)")
        ("map-binning", po::value(&s.map_binning)->value_name("B")
             ->notifier(in_range("map-binning", 1L, 100000L)),
         "field pixels per map pixel (default: a map at most 1024 pixels a side)")
        ("no-magnify", po::bool_switch(&s.no_magnify),
         "keep every galaxy's flux (shear and size only; by default flux and area grow by mu)")
        ("max-shear", po::value(&s.limits.max_shear)->value_name("G")->default_value(0.5)
             ->notifier(in_range("max-shear", 1e-6, 0.999)),
         "the strongest reduced shear |g| drawn: the lens acts on a galaxy as one matrix, which "
         "near a critical curve stretches it into a straight bar, not an arc")
        ("max-magnification", po::value(&s.limits.max_magnification)->value_name("MU")
             ->default_value(10.0)
             ->notifier(in_range("max-magnification", 1.0, 1e6)),
         "the largest magnification drawn (the same reason)")
        ("drop-strong", po::bool_switch(&s.drop_strong),
         "leave out galaxies beyond weak lensing (kappa >= 1, |g| > --max-shear, mu > "
         "--max-magnification); by default they are an error");
    options.positional("input", 1);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-lens", options.common().verbosity);

    if (!s.shear.empty() && s.shear.size() != 2)
        throw po::error("--shear takes two numbers: G1 G2");
    if (s.halos.size() % 5 != 0)
        throw po::error("--halo takes five numbers each: X Y M200 C Z");
    if (!s.halos.empty() && !options.given("source-z"))
        throw po::error("--halo needs --source-z (the lensed galaxies' redshift)");
    if (!s.b_power.empty() && s.power.empty())
        throw po::error("--b-power needs --power-spectrum (the E mode)");
    for (const char* name : {"spacing", "padding"})
        if (options.given(name) && s.power.empty())
            throw po::error(std::string("--") + name + ": only with --power-spectrum");
    if (s.shear.empty() && !options.given("kappa") && s.halos.empty() && s.power.empty())
        throw po::error("no lens: give --power-spectrum, --halo or --shear/--kappa");
    const FieldGeometry field = s.field.field(options);

    LensingSources lenses;
    if (!s.shear.empty()) {
        lenses.constant.gamma1 = s.shear[0];
        lenses.constant.gamma2 = s.shear[1];
    }
    lenses.constant.kappa = s.kappa;
    for (std::size_t k = 0; k < s.halos.size(); k += 5) {
        const NfwHalo halo{s.halos[k], s.halos[k + 1], s.halos[k + 2], s.halos[k + 3],
                           s.halos[k + 4]};
        try {
            lenses.halos.emplace_back(halo, s.cosmology, s.source_z, field.pixel_scale);
        } catch (const Error& e) {
            throw Error("halo " + std::to_string(k / 5 + 1) + ": " + e.message(), "", 0,
                        e.field().empty() ? "halo" : e.field());
        }
        log.verbose("halo ", k / 5 + 1, ": r_s ", lenses.halos.back().r_s_arcsec(),
                    " arcsec, kappa_s ", lenses.halos.back().kappa_s());
    }
    if (!s.power.empty()) {
        const PowerSpectrum e = read_power_spectrum(s.power);
        std::optional<PowerSpectrum> b;
        if (!s.b_power.empty()) b = read_power_spectrum(s.b_power);
        s.gaussian.seed = options.common().seed;
        lenses.gaussian.emplace(e, b, field, s.gaussian);
        const GaussianLensingField& g = *lenses.gaussian;
        const double ell_min =
            2.0 * pi / (std::max(field.nx, field.ny) * field.pixel_scale * arcsec);
        log.verbose("random field: ", g.nodes_x(), " x ", g.nodes_y(), " nodes ", g.node_spacing(),
                    " arcsec apart; ell from ", ell_min, " (the field) to ", g.ell_limit());
        if (e.ell_min() > ell_min || e.ell_max() < g.ell_limit())
            log.info("note: ", s.power, " covers ell ", e.ell_min(), " - ", e.ell_max(),
                     ", the field ", ell_min, " - ", g.ell_limit(), ": no power outside the table");
    }

    if (!s.map.empty()) write_map(s.map, lenses, field, s.map_binning, log);

    AtomicTextFile file(options.common().output_or_stdout());
    JsonlReader reader(s.input, {ObjectRecord::schema});
    JsonlWriter out(file.stream(), file.name());
    ObjectRecord r;
    long galaxies = 0, dropped = 0, in_rings = 0;
    double sum_g2 = 0.0, max_g = 0.0, sum_kappa = 0.0;
    while (reader.next_record(r)) {
        if (r.kind == "galaxy") {
            if (r.lensing)
                throw reader.locate(Error("object " + r.id + " is already lensed: give every lens "
                                          "to one run of shapesim-lens", "", 0, "lensing"));
            if (!r.x || !r.y)
                throw reader.locate(Error("object " + r.id + " has no x, y: sample it with --like "
                                          "or a field", "", 0, "x"));
            // A ring of rotated copies (shapesim-sample --ring) shares one lensing: its first
            // copy's, so its shape noise cancels in the mean shear.
            double at_x = *r.x, at_y = *r.y;
            if (const auto ring = r.extra.find("ring"); ring != r.extra.end() &&
                                                        ring->is_object() && ring->contains("x") &&
                                                        ring->contains("y")) {
                at_x = as_double((*ring)["x"], "ring.x");
                at_y = as_double((*ring)["y"], "ring.y");
                ++in_rings;
            }
            const Convergence c = lenses.at(at_x, at_y);
            const std::optional<Lensing> l = reduced(c, !s.no_magnify, s.limits);
            if (!l) {
                if (s.drop_strong) {
                    ++dropped;
                    continue;
                }
                throw reader.locate(
                    Error("object " + r.id + " at (" + std::to_string(*r.x) + ", " +
                              std::to_string(*r.y) + ") is strongly lensed (kappa " +
                              std::to_string(c.kappa) + ", gamma (" + std::to_string(c.gamma1) +
                              ", " + std::to_string(c.gamma2) +
                              ")): beyond weak lensing (kappa >= 1, |g| > --max-shear or mu > "
                              "--max-magnification; see --drop-strong)",
                          "", 0, "lensing"));
            }
            r.lensing = l;
            ++galaxies;
            const double g = std::hypot(l->g1, l->g2);
            sum_g2 += g * g;
            max_g = std::max(max_g, g);
            sum_kappa += l->kappa;
        }
        out.write(r.to_json());
    }
    file.commit();
    if (galaxies > 0)
        log.info(galaxies, " galaxies lensed: rms |g| ", std::sqrt(sum_g2 / double(galaxies)),
                 ", largest ", max_g, ", mean kappa ", sum_kappa / double(galaxies),
                 dropped ? ", " + std::to_string(dropped) + " strongly lensed left out" : "",
                 in_rings ? ", " + std::to_string(in_rings) +
                                " in rings (each ring lensed as its first copy)"
                          : "");
    else
        log.info("no galaxy to lens",
                 dropped ? " (" + std::to_string(dropped) + " strongly lensed left out)" : "");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-lens", run); }
