// FITS input and output (cfitsio, kept out of this header).
//
// Pixels: a 2D image of any BITPIX is read into an ImageArray of doubles with
//   image(j, i) = pixel at FITS (x, y) = (i + 1, j + 1),
// BSCALE/BZERO applied and blank pixels (BLANK, or NaN in float images) read as NaN. This file
// and image.hpp are the only places where 1-based FITS pixels meet 0-based arrays.
//
// Places: every path may carry cfitsio's extended syntax, `file.fits[SCI]` or `file.fits[2]`
// (extension numbers count from 0 = primary HDU). Errors name the file and HDU the way a user
// would type them, plus the keyword: `hdf.fits[SCI]: NAXIS1: image is empty`. Every cfitsio
// status passes one helper that turns it into shapesim::Error with cfitsio's own text.
//
// Output: FitsWriter writes a multi-extension file atomically (atomic_file.hpp): HDU 0 is
// empty and carries provenance (PROGRAM, VERSION, CFITSIO, caller's keywords such as the
// options; no DATE, so reruns are bit-identical); each image goes into its own extension
// with EXTNAME, BUNIT, WCS, extra keywords and HISTORY. Float images are BITPIX −32 (or
// −64 where precision is the point).
//
// Stamps (DESIGN §2): one MEF file; per object an image HDU `<id>.image`, a weight (inverse
// variance) HDU `<id>.weight` and a mask HDU `<id>.mask` (non-zero = pixel owned by a
// neighbour). The suffix keeps `stamps.fits[17.image]` a name: cfitsio would read a bare
// `[17]` as extension number 17 (and some names, e.g. `[F32]`, as other syntax; move_to()
// by EXTNAME is never ambiguous). Each stamp HDU records where it sits in its parent image
// as IRAF's LTV1/LTV2 (physical = logical − LTV), which ds9 shows as "physical" coordinates.
#pragma once

#include "shapesim/error.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/image.hpp"

#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

namespace shapesim {

/// Which HDU a FitsReader starts at when the path names none.
enum class FitsStart {
    as_given,     ///< the primary HDU (cfitsio `fits_open_file`)
    first_image,  ///< the first HDU holding an image with NAXIS > 0 (`fits_open_image`)
};

/// Size of a 2D image in pixels.
struct ImageSize {
    int nx = 0;  ///< NAXIS1, along x (columns)
    int ny = 0;  ///< NAXIS2, along y (rows)
};

/// One HDU of a file, as listed by FitsReader::list_hdus.
struct FitsHduInfo {
    int index = 0;                 ///< extension number as in `file.fits[n]`; 0 = primary
    std::string extname;           ///< EXTNAME, empty when absent
    bool is_image = false;         ///< an image HDU (false: a table)
    std::vector<long long> naxes;  ///< NAXISn of an image; empty when NAXIS = 0
};

/// A FITS file open for reading, positioned at one HDU (RAII; move-only).
class FitsReader {
public:
    /// Open `path` read-only; an HDU given in the path (`[EXT]`, `[n]`) is selected.
    /// Throws Error naming the path when the file is missing or not FITS.
    explicit FitsReader(const std::string& path, FitsStart start = FitsStart::as_given);
    ~FitsReader();
    FitsReader(FitsReader&&) noexcept;
    FitsReader& operator=(FitsReader&&) noexcept;

    /// The file name without any `[...]` part.
    const std::string& file() const;
    /// The current HDU as a user would type it: `file.fits[EXTNAME]`, else `file.fits[n]`,
    /// and plain `file.fits` for a primary HDU without EXTNAME.
    const std::string& place() const;
    /// Current HDU as an extension number (0 = primary).
    int hdu_index() const;

    /// Number of HDUs in the file.
    int hdu_count();
    /// Every HDU of the file (the current HDU is kept).
    std::vector<FitsHduInfo> list_hdus();
    /// Move to extension number `index` (0 = primary); Error when there is none.
    void move_to(int index);
    /// Move to the HDU whose EXTNAME is `extname` (case-insensitive, as cfitsio); Error when
    /// there is none.
    void move_to(const std::string& extname);
    /// True when an HDU has this EXTNAME (the current HDU is kept).
    bool has_hdu(const std::string& extname);

    /// Size of the current HDU's image; Error unless it is a non-empty 2D image (trailing axes
    /// of length 1 are allowed).
    ImageSize image_size();
    /// The current HDU's image as doubles (see the file comment for the index convention).
    ImageArray read_image();
    /// The `nx` × `ny` pixels of the current HDU's image whose first pixel is FITS (`x0`, `y0`),
    /// as doubles like read_image(); Error unless that window lies within the image.
    ImageArray read_region(long x0, long y0, long nx, long ny);

    /// Rows of the current HDU's table (binary or ASCII); Error unless it is a table, or when
    /// the header declares more rows than the file holds.
    long table_rows();
    /// True when the current table has a column `name` (case-insensitive).
    bool has_column(const std::string& name);
    /// True when column `name` of the current table holds text; Error when it is absent.
    bool column_is_text(const std::string& name);
    /// Numeric column `name` of the current table, one value per row (integers converted,
    /// undefined values NaN); Error naming the place and column when it is absent, text, or
    /// holds more than one value per row.
    std::vector<double> read_column(const std::string& name);
    /// Every value of numeric column `name` in table row `row` (1-based): a vector cell such as
    /// PSFEx's PSF_MASK. Error naming the place and column when it is absent, text, the row
    /// is not in the table, or the cell holds more than `max_values` values.
    std::vector<double> read_cell(const std::string& name, long row, long max_values);
    /// Text column `name` of the current table, trailing blanks removed; Error naming the place
    /// and column when it is absent or not text.
    std::vector<std::string> read_text_column(const std::string& name);

    /// True when the current header has keyword `key`.
    bool has_key(const std::string& key);
    /// A numeric keyword; nullopt when absent or undefined, Error when not a finite number.
    std::optional<double> optional_double(const std::string& key);
    /// A numeric keyword; Error naming the place and keyword when absent or not numeric.
    double required_double(const std::string& key);
    /// An integer keyword (nullopt when absent or undefined).
    std::optional<long long> optional_int(const std::string& key);
    long long required_int(const std::string& key);
    /// A string keyword (long strings through CONTINUE cards; trailing blanks removed).
    std::optional<std::string> optional_string(const std::string& key);
    std::string required_string(const std::string& key);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The image of `path`: the HDU named in the path, else the first HDU with an image.
ImageArray read_fits_image(const std::string& path);

/// A header keyword to write. Numbers are written so they read back exactly.
struct FitsKeyword {
    std::string name;  ///< up to 8 characters, or longer (then written as HIERARCH)
    std::variant<double, long long, bool, std::string> value;
    std::string comment;

    FitsKeyword(std::string name_, bool value_, std::string comment_ = {})
        : name(std::move(name_)), value(value_), comment(std::move(comment_)) {}
    FitsKeyword(std::string name_, std::string value_, std::string comment_ = {})
        : name(std::move(name_)), value(std::move(value_)), comment(std::move(comment_)) {}
    FitsKeyword(std::string name_, const char* value_, std::string comment_ = {})
        : FitsKeyword(std::move(name_), std::string(value_), std::move(comment_)) {}
    /// Any integer type (stored as long long) or floating type (stored as double).
    template <class T,
              std::enable_if_t<std::is_arithmetic_v<T> && !std::is_same_v<T, bool>, int> = 0>
    FitsKeyword(std::string name_, T value_, std::string comment_ = {})
        : name(std::move(name_)), comment(std::move(comment_)) {
        if constexpr (std::is_integral_v<T>)
            value = static_cast<long long>(value_);
        else
            value = static_cast<double>(value_);
    }
};

/// True when every finite non-zero pixel of `image` is a normal float (1.2e−38 … 3.4e38 in
/// magnitude), so BITPIX −32 loses only precision, never a value.
bool fits_in_float(const ImageArray& image);

/// One column of a binary table to write (FitsWriter::write_table): TTYPE `name`, TUNIT `unit`
/// (empty: none) and one cell a row, whose type makes TFORM: 1K (64-bit integers), 1D (doubles),
/// 1L (logicals) or nA (text, n its longest value).
struct FitsColumn {
    std::string name;
    std::string unit;
    std::variant<std::vector<long long>, std::vector<double>, std::vector<bool>,
                 std::vector<std::string>>
        cells;
};

/// How to write one image HDU.
struct FitsImageSpec {
    std::string extname;     ///< EXTNAME (empty: none)
    int bitpix = -32;        ///< −32 or −64 (−32 becomes −64 unless fits_in_float); 8, 16 or
                             ///< 32 for masks and labels
    std::string bunit;       ///< BUNIT (empty: none)
    std::optional<Wcs> wcs;  ///< WCS: CTYPE, CUNIT, CRPIX, CRVAL, CD, RADESYS, PV, SIP
    std::vector<FitsKeyword> keywords;
    std::vector<std::string> history;  ///< HISTORY cards (long lines are wrapped)
};

/// A multi-extension FITS file written atomically: nothing appears at `path` until commit().
class FitsWriter {
public:
    /// Start `path` (checked writable; `.gz` and `[...]` refused). HDU 0 gets PROGRAM
    /// (`program`), VERSION (version.hpp), CFITSIO (no DATE: reruns give the same bytes), then
    /// `primary_keywords` (e.g. the options, as HIERARCH) and `primary_history`.
    FitsWriter(const std::string& path, const std::string& program,
               const std::vector<FitsKeyword>& primary_keywords = {},
               const std::vector<std::string>& primary_history = {});
    /// Unless committed, closes and removes the temporary file.
    ~FitsWriter();
    FitsWriter(FitsWriter&&) noexcept;
    FitsWriter& operator=(FitsWriter&&) noexcept;

    /// The final path.
    const std::string& path() const;
    /// Append `image` as a new image HDU. Integer BITPIX needs finite values in range.
    void write_image(const ImageArray& image, const FitsImageSpec& spec);
    /// Append an ny × nx image HDU whose rows come in order by write_rows(), so the image need
    /// not be held whole. Its BITPIX is spec.bitpix as given (−32 is not promoted).
    void begin_image(long ny, long nx, const FitsImageSpec& spec);
    /// The next rows of the image begun. FloatRangeError when BITPIX is −32 and a value is
    /// beyond a float (write the image whole, with write_image, to have it promoted).
    void write_rows(const ImageArray& rows);
    /// Append `columns` (at least one, at most 999, of one length) as a binary-table HDU named
    /// `extname`, `keywords` in its header; text cells NUL-padded, as astropy and numpy strip.
    void write_table(const std::vector<FitsColumn>& columns, const std::string& extname,
                     const std::vector<FitsKeyword>& keywords = {});
    /// Close the file and rename it onto `path`. Throws Error; the writer is then finished.
    void commit();

private:
    std::string start_hdu(long ny, long nx, int bitpix, const FitsImageSpec& spec);
    void write_pixels(const ImageArray& pixels, long long first, const std::string& place,
                      int bitpix);
    /// `pixels` as a BITPIX −32 data unit holds them, into the writer's buffer; false (buffer
    /// unusable) when one does not fit a float.
    bool to_floats(const ImageArray& pixels);
    void write_floats(long long first, const std::string& place);  ///< that buffer, at `first`
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// A value a BITPIX −32 image begun row by row cannot hold (FitsWriter::write_rows).
class FloatRangeError : public Error {
public:
    using Error::Error;
};

/// One object's postage stamp (DESIGN §2). All three planes have the same size.
struct Stamp {
    std::string id;
    ImageArray image;    ///< pixels, image units
    ImageArray weight;   ///< inverse variance; 0 = excluded
    ImageArray mask;     ///< non-zero where the pixel belongs to a neighbour
    int x0 = 1, y0 = 1;  ///< parent-image FITS pixel of the stamp's pixel (1, 1)
};

/// EXTNAMEs of a stamp's planes: `<id>.image`, `<id>.weight`, `<id>.mask`.
std::string stamp_image_extname(const std::string& id);
std::string stamp_weight_extname(const std::string& id);
std::string stamp_mask_extname(const std::string& id);

/// Read object `id`'s stamp (three HDUs); Error when a plane is missing or sizes differ.
Stamp read_stamp(FitsReader& fits, const std::string& id);
/// Append a stamp as three HDUs: image and weight BITPIX −32 (−64 beyond a float's range),
/// mask BITPIX 8.
void write_stamp(FitsWriter& out, const Stamp& stamp);

// The FITS side of a WCS (fits_wcs.cpp).

/// Read the celestial WCS of the current HDU: CTYPEi, CRPIXi, CRVALi, the CD matrix (else
/// PCi_j × CDELTi, else CDELTi with CROTA2), PVi_m, LONPOLE, LATPOLE, RADESYS and SIP terms.
/// Throws Error naming the file/HDU and keyword.
Wcs read_wcs(FitsReader& fits);
/// True when the current HDU declares a celestial WCS (CTYPE1 present).
bool has_wcs(FitsReader& fits);

/// The geometry of the first image HDU of `path` (cfitsio syntax `file.fits[EXT]` allowed).
/// Its header's WCS when it has one (CTYPE1 present and not blank); otherwise, with
/// `pixel_scale`, a north-up TAN WCS centred on (`ra`, `dec`) as shapesim-detect assumes;
/// otherwise Error naming the file. Pixels are not read.
FieldGeometry read_field_geometry(const std::string& path,
                                  std::optional<double> pixel_scale = std::nullopt,
                                  double ra = 0.0, double dec = 0.0);

namespace detail {
/// The one door for cfitsio statuses (Gnuastro's gal_fits_io_error), shared by the reading
/// (fits_io.cpp) and writing (fits_write.cpp) sides: a non-zero status becomes an Error with
/// cfitsio's short text (or `instead`), the place and the keyword.
void fits_check(int status, const std::string& place, const std::string& keyword = {},
                const std::string& instead = {});
}  // namespace detail

}  // namespace shapesim
