// shapesim-table: a JSON-lines catalogue (any shapesim schema) → a FITS binary table with
// TUNIT, or ECSV, for TOPCAT, astropy, fv and the tools astronomers open catalogues with.
// The work is in the library: table.hpp (columns, units, ECSV) and fits_io.hpp (the FITS table).
#include "app/log.hpp"
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/table.hpp"

#include <cctype>
#include <string>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Turn a JSON-lines catalogue (detect's sources, decompose's models, sample's objects,\n"
    "render's truth, measure's morphology) into a table: a FITS binary table (-o NAME.fits:\n"
    "TUNIT per column, EXTNAME from the schema, SCHEMA card) or ECSV (-o NAME.ecsv, or\n"
    "stdout: astropy's Table.read reads its units and types). Fields become columns in the\n"
    "order first met; a nested object's fields become outer_inner; flags become one\n"
    "comma-separated text; arrays of numbers (a model's coefficients) are left out, and named\n"
    "on stderr. Units follow the field names: deg, pix, arcsec, mag; fluxes take --flux-unit\n"
    "or the BUNIT of the --like image.\n"
    "\n"
    "Examples:\n"
    "  shapesim-table truth.jsonl -o truth.fits --like image.fits\n"
    "  shapesim-table --flux-unit electron/s objects.jsonl -o objects.ecsv\n"
    "  shapesim-measure image.fits | shapesim-table > morph.ecsv";

struct Settings {
    std::string input = "-", format, flux_unit;
};

std::string extension(const std::string& path) {
    const auto dot = path.rfind('.');
    if (dot == std::string::npos || path.find('/', dot) != std::string::npos) return {};
    std::string e = path.substr(dot + 1);
    for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

// EXTNAME from the schema: "shapesim.truth/1" → "TRUTH".
std::string extname(const std::string& schema) {
    std::string name = schema;
    if (const auto dot = name.find('.'); dot != std::string::npos) name = name.substr(dot + 1);
    if (const auto slash = name.find('/'); slash != std::string::npos) name.resize(slash);
    for (char& c : name) c = char(std::toupper(static_cast<unsigned char>(c)));
    return name.empty() ? "CATALOGUE" : name;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-table", "[OPTION]... [FILE]", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::like |
                                    app::Common::print_params);
    Settings s;
    options.group("Table").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "JSON-lines catalogue, or the first argument (default: stdin)")
        ("format", po::value(&s.format)->value_name("fits|ecsv"),
         "the table's format (default: from -o's extension; stdout: ecsv)")
        ("flux-unit", po::value(&s.flux_unit)->value_name("UNIT"),
         "unit of the flux columns, as FITS writes it (electron/s, adu, ...; default: the "
         "--like image's BUNIT, else none)");
    options.positional("input", 1);
    if (!options.parse(argc, argv)) return 0;
    const std::string output = options.common().output_or_stdout();
    std::string format = s.format;
    if (format.empty()) format = output == "-" ? "ecsv" : extension(output);
    if (format == "fit" || format == "fts") format = "fits";
    if (format != "fits" && format != "ecsv")
        throw po::error(s.format.empty()
                            ? "cannot tell the format from '" + output +
                                  "': give --format fits|ecsv"
                            : "--format must be fits or ecsv, not '" + s.format + "'");
    if (format == "fits" && output == "-")
        throw po::error("a FITS table needs a file: give -o NAME.fits");
    std::string flux_unit = s.flux_unit;
    if (!options.given("flux-unit") && !options.common().like.empty()) {
        FitsReader like(options.common().like, FitsStart::first_image);
        flux_unit = like.optional_string("BUNIT").value_or("");
    }
    app::Log log("shapesim-table", options.common().verbosity);
    JsonlReader reader(s.input, {});
    const CatalogueTable table = read_table(reader, flux_unit);
    if (table.rows == 0) throw Error("no record to write", reader.name());
    if (format == "fits") {
        FitsWriter fits(output, "shapesim-table");
        write_fits_table(fits, table, extname(table.schema));
        fits.commit();
    } else {
        AtomicTextFile file(output);
        write_ecsv(file.stream(), table);
        file.commit();
    }
    for (const std::string& name : table.skipped)
        log.info("left out ", name, ": an array of numbers per record");
    log.verbose(table.rows, " rows, ", table.columns.size(), " columns of ", table.schema,
                " written to ", output);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-table", run); }
