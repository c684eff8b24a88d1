// Catalogue tables: the records of a JSON-lines catalogue as typed columns with units, for the
// tools astronomers open catalogues with (a FITS binary table through fits_io's
// FitsWriter::write_table; ECSV, astropy's text table, here).
//
// Columns are the records' fields in the order first met; a nested object's fields become
// `outer_inner`; an array of strings (flags) one comma-separated text; an array of numbers (a
// model's coefficients) is left out and named in `skipped`. A field a record lacks, or holds
// as null, is null there: NaN in a real column (an integer or boolean column with a null is
// written as real), an empty text. Units come from the field's name (records.hpp
// field_unit): degrees, pixels, arcsec, mag, and the image unit for fluxes when it is known.
#pragma once

#include "shapesim/fits_io.hpp"

#include <iosfwd>
#include <map>
#include <string>
#include <vector>

namespace shapesim {

class JsonlReader;

struct CatalogueColumn {
    enum class Type { integer, real, boolean, text };
    std::string name;
    std::string unit;               ///< FITS/astropy unit string; empty: none (dimensionless)
    Type type = Type::integer;      ///< the widest type its values need
    std::vector<double> numbers;    ///< integer, real and boolean cells (NaN: null)
    std::vector<std::string> texts; ///< text cells
    bool has_null = false;
};

struct CatalogueTable {
    std::string schema;                 ///< the records' schema (one per table)
    long rows = 0;
    std::vector<CatalogueColumn> columns;
    std::vector<std::string> skipped;   ///< fields holding arrays of numbers, left out
};

/// Every record of `reader` as one table; Error (file, line) for a record whose schema differs
/// from the first's, a field whose type changes between text and number, or an integer beyond
/// 2^53. `flux_unit` is the unit of the flux fields (empty: none).
CatalogueTable read_table(JsonlReader& reader, const std::string& flux_unit);

/// `table` as ECSV 1.0 (astropy's enhanced CSV: a YAML header of names, units and types, then
/// space-separated rows; reals in shortest round-trip form, null reals as nan).
void write_ecsv(std::ostream& out, const CatalogueTable& table);

/// `table` as a binary-table HDU named `extname` of `out` (FitsWriter::write_table): integer
/// columns as 64-bit integers, real as doubles, boolean as logicals, text as text; a SCHEMA card
/// names the records' schema.
void write_fits_table(FitsWriter& out, const CatalogueTable& table, const std::string& extname);

/// Numeric columns of any catalogue a user has on disk, by name (case-sensitive; FITS names
/// case-insensitive, as cfitsio): JSON lines (each line an object; top-level numbers; null or
/// absent is NaN), a FITS table (`file.fits[EXT]`, else the first table HDU holding the
/// columns: SExtractor's FITS_LDAC too), SExtractor's ASCII_HEAD ("#   3 X_IMAGE …" header
/// lines, then whitespace-separated rows), or CSV (a header line of names, then comma-separated
/// rows; empty cells NaN). The format is told by the extension (.fits .fit .fts .ldac; .csv)
/// and, for text, by the first line. Every name in `required` must be there (Error naming the
/// file and the column); `optional` ones absent are left out of the map. At most `max_rows`.
std::map<std::string, std::vector<double>> read_numeric_columns(
    const std::string& path, const std::vector<std::string>& required,
    const std::vector<std::string>& optional = {}, long max_rows = 100000000L);

}  // namespace shapesim
