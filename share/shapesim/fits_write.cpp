// FITS writing: FitsWriter (atomic multi-extension files: images whole or row by row, binary
// tables, keywords, the WCS, HISTORY) and postage stamps; reading is fits_io.cpp.
#include "shapesim/fits_io.hpp"
#include "shapesim/version.hpp"

#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <variant>

namespace shapesim {

using detail::fits_check;

namespace {

// Fewest significant digits (15–17) that read back as the same double, so headers stay
// readable (0.04, not 0.040000000000000001) and exact.
int round_trip_digits(double value) {
    char text[40];
    for (int digits = 15; digits < 17; ++digits) {
        std::snprintf(text, sizeof text, "%.*G", digits, value);
        if (std::strtod(text, nullptr) == value) return digits;
    }
    return 17;
}

void write_keyword(fitsfile* f, const FitsKeyword& key, const std::string& place) {
    const char* name = key.name.c_str();
    char* comment = key.comment.empty() ? nullptr : const_cast<char*>(key.comment.c_str());
    int status = 0;
    if (const auto* d = std::get_if<double>(&key.value)) {
        if (!std::isfinite(*d)) throw Error("cannot write a non-finite value", place, 0, key.name);
        fits_update_key_dbl(f, name, *d, -round_trip_digits(*d), comment, &status);
    } else if (const auto* i = std::get_if<long long>(&key.value)) {
        fits_update_key_lng(f, name, *i, comment, &status);
    } else if (const auto* b = std::get_if<bool>(&key.value)) {
        fits_update_key_log(f, name, *b ? 1 : 0, comment, &status);
    } else {
        const std::string& s = std::get<std::string>(key.value);
        fits_update_key_longstr(f, name, const_cast<char*>(s.c_str()), comment, &status);
    }
    fits_check(status, place, key.name);
}

void write_history(fitsfile* f, const std::vector<std::string>& lines, const std::string& place) {
    int status = 0;
    for (const auto& line : lines) fits_write_history(f, line.c_str(), &status);
    fits_check(status, place, "HISTORY");
}

void write_wcs(fitsfile* f, const Wcs& written, const std::string& place) {
    const WcsKeywords& wcs = written.keywords();
    const std::vector<FitsKeyword> keys = {
        {"CTYPE1", wcs.ctype1},
        {"CTYPE2", wcs.ctype2},
        {"CUNIT1", "deg"},
        {"CUNIT2", "deg"},
        {"CRPIX1", wcs.crpix1, "reference pixel (FITS coordinates)"},
        {"CRPIX2", wcs.crpix2},
        {"CRVAL1", wcs.crval1, "RA at the reference pixel, degrees"},
        {"CRVAL2", wcs.crval2, "Dec at the reference pixel, degrees"},
        {"CD1_1", wcs.cd1_1, "degrees per pixel"},
        {"CD1_2", wcs.cd1_2},
        {"CD2_1", wcs.cd2_1},
        {"CD2_2", wcs.cd2_2},
        {"RADESYS", wcs.radesys, "frame of RA/Dec"}};
    for (const auto& key : keys) write_keyword(f, key, place);
    if (wcs.lonpole) write_keyword(f, {"LONPOLE", *wcs.lonpole}, place);
    if (wcs.latpole) write_keyword(f, {"LATPOLE", *wcs.latpole}, place);
    for (const auto& pv : wcs.pv)  // projection parameters, TPV terms
        write_keyword(f, {"PV" + std::to_string(pv.i) + "_" + std::to_string(pv.m), pv.value},
                      place);
    if (wcs.has_sip()) {  // the distortion travels with the WCS (a render --like keeps it)
        for (const char* order : {"A_ORDER", "B_ORDER"})
            write_keyword(f, {order, (long long)wcs.sip_order, "SIP polynomial order"}, place);
        for (const auto& [prefix, terms] : {std::pair{"A", &wcs.sip_a}, std::pair{"B", &wcs.sip_b}})
            for (std::size_t p = 0; p < terms->size(); ++p)
                for (std::size_t q = 0; q < (*terms)[p].size(); ++q)
                    if ((*terms)[p][q] != 0.0)
                        write_keyword(f, {std::string(prefix) + "_" + std::to_string(p) + "_" +
                                              std::to_string(q),
                                          (*terms)[p][q]},
                                      place);
    }
    if (wcs.radesys == "FK5" || wcs.radesys == "FK4")
        write_keyword(f, {"EQUINOX", wcs.radesys == "FK5" ? 2000.0 : 1950.0}, place);
}

bool valid_bitpix(int bitpix) {
    return bitpix == 8 || bitpix == 16 || bitpix == 32 || bitpix == -32 || bitpix == -64;
}

}  // namespace

struct FitsWriter::Impl {
    AtomicFile file;  // declared first: destroyed after the cfitsio handle is closed
    fitsfile* f = nullptr;
    int images = 0;
    // The image begun by begin_image: its place, width, rows still to come, next element.
    std::string open_place;
    long open_nx = 0, open_rows_left = 0;
    int open_bitpix = 0;
    LONGLONG next_element = 1;
    std::vector<std::uint32_t> floats;  ///< BITPIX −32 pixels as written (big-endian), reused

    explicit Impl(const std::string& path) : file(path) {}
    ~Impl() { close_quietly(); }
    void close_quietly() {
        int status = 0;
        if (f) fits_close_file(f, &status);
        f = nullptr;
        fits_clear_errmsg();
    }
};

FitsWriter::FitsWriter(const std::string& path, const std::string& program,
                       const std::vector<FitsKeyword>& primary_keywords,
                       const std::vector<std::string>& primary_history) {
    if (path == "-") throw Error("writing FITS to stdout is not supported; give a file name");
    if (path.find('[') != std::string::npos)
        throw Error("an output path cannot carry [...] specifiers", path);
    if (path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0)
        throw Error("compressed (.gz) output is not supported", path);
    check_writable(path);
    impl_ = std::make_unique<Impl>(path);
    // cfitsio's "!" would remove a device to create a file in its place.
    if (impl_->file.direct())
        throw Error("cannot write a FITS file to a device or a pipe; give a file name", path);
    // "!" lets cfitsio replace a stale temporary of a crashed run with the same pid.
    int status = 0;
    fits_create_file(&impl_->f, ("!" + impl_->file.temp_path()).c_str(), &status);
    if (status != 0) impl_->f = nullptr;
    fits_check(status, path);
    fits_create_img(impl_->f, BYTE_IMG, 0, nullptr, &status);
    fits_check(status, path);
    const std::string cfitsio = std::to_string(CFITSIO_MAJOR) + "." +
                                std::to_string(CFITSIO_MINOR) + "." + std::to_string(CFITSIO_MICRO);
    write_keyword(impl_->f, {"PROGRAM", program, "program that wrote this file"}, path);
    write_keyword(impl_->f, {"VERSION", version(), "shapesim version (git describe)"}, path);
    // No DATE card: the same inputs and seed must give the same bytes (DESIGN §6), whenever run.
    write_keyword(impl_->f, {"CFITSIO", cfitsio, "cfitsio version"}, path);
    for (const auto& key : primary_keywords) write_keyword(impl_->f, key, path);
    write_history(impl_->f, primary_history, path);
}

FitsWriter::~FitsWriter() = default;
FitsWriter::FitsWriter(FitsWriter&&) noexcept = default;
FitsWriter& FitsWriter::operator=(FitsWriter&&) noexcept = default;

const std::string& FitsWriter::path() const { return impl_->file.target(); }

// cfitsio's byte-level writer, exported but declared only in its internal fitsio2.h (which
// lacks extern "C" and defines many macros): what fits_write_img calls once it has converted.
extern "C" int ffpbyt(fitsfile* fptr, LONGLONG nbytes, void* buffer, int* status);
constexpr int cfitsio_ignore_eof = 1;  // fitsio2.h's IGNORE_EOF: a position past the end is fine

namespace {

// Whether every one of n doubles fits a float (NaN and ±inf are written as they are, 0 is a
// float; what is below the smallest normal float or above the largest does not) and, when
// `out` is given, the floats as a BITPIX −32 data unit holds them: float(v), big-endian —
// cfitsio's own conversion, without its copy and byte swap. Four pixels a lane group, blocks
// of 4096 without an early exit (a pass over every written pixel: 16.7 M for a 4096² scene).
__attribute__((target_clones("avx2", "default"))) bool float_bytes(const double* in, std::size_t n,
                                                                  std::uint32_t* out) {
    using Doubles4 = double __attribute__((vector_size(32)));
    using Bits4 = std::int64_t __attribute__((vector_size(32)));
    using Floats4 = float __attribute__((vector_size(16)));
    using Bytes16 = unsigned char __attribute__((vector_size(16)));
    constexpr double lowest = std::numeric_limits<float>::min();  // smallest normal float
    constexpr double highest = std::numeric_limits<float>::max();
    constexpr double inf = std::numeric_limits<double>::infinity();
    constexpr std::size_t block = 4096;
    std::size_t k = 0;
    for (; k + block <= n; k += block) {
        Bits4 any = {0, 0, 0, 0};
        for (std::size_t i = k; i < k + block; i += 4) {
            Doubles4 v;
            std::memcpy(&v, in + i, sizeof v);
            const Doubles4 a = Doubles4(Bits4(v) & std::numeric_limits<std::int64_t>::max());
            any |= ((a < lowest) & (a != 0.0)) | ((a > highest) & (a != inf));
            if (!out) continue;
            const Bytes16 bytes = Bytes16(__builtin_convertvector(v, Floats4));
            const Bytes16 swapped = __builtin_shufflevector(bytes, bytes, 3, 2, 1, 0, 7, 6, 5, 4,
                                                            11, 10, 9, 8, 15, 14, 13, 12);
            std::memcpy(out + i, &swapped, sizeof swapped);
        }
        if (any[0] | any[1] | any[2] | any[3]) return false;
    }
    for (; k < n; ++k) {
        const double a = std::abs(in[k]);
        if ((a < lowest && a != 0.0) || (a > highest && a != inf)) return false;
        if (!out) continue;
        const float f = float(in[k]);
        std::uint32_t word;
        std::memcpy(&word, &f, sizeof word);
        out[k] = __builtin_bswap32(word);
    }
    return true;
}

}  // namespace

bool fits_in_float(const ImageArray& image) {
    return float_bytes(image.data(), std::size_t(image.size()), nullptr);
}

// The header of a new ny × nx image HDU of BITPIX `bitpix`; returns its place.
std::string FitsWriter::start_hdu(long ny, long nx, int bitpix, const FitsImageSpec& spec) {
    require(impl_ && impl_->f, "FitsWriter: an image after commit");
    require(impl_->open_rows_left == 0, "FitsWriter: the image begun is not finished");
    const std::string place =
        path() + "[" + (spec.extname.empty() ? std::to_string(impl_->images + 1) : spec.extname) +
        "]";
    if (!valid_bitpix(spec.bitpix))
        throw Error("BITPIX must be 8, 16, 32, -32 or -64, got " + std::to_string(spec.bitpix),
                    place, 0, "BITPIX");
    if (ny <= 0 || nx <= 0) throw Error("cannot write an empty image", place, 0, "NAXIS");
    int status = 0;
    long naxes[2] = {nx, ny};
    fits_create_img(impl_->f, bitpix, 2, naxes, &status);
    fits_check(status, place);
    ++impl_->images;
    if (!spec.extname.empty()) write_keyword(impl_->f, {"EXTNAME", spec.extname}, place);
    if (!spec.bunit.empty()) write_keyword(impl_->f, {"BUNIT", spec.bunit, "pixel unit"}, place);
    if (spec.wcs) write_wcs(impl_->f, *spec.wcs, place);
    for (const auto& key : spec.keywords) write_keyword(impl_->f, key, place);
    write_history(impl_->f, spec.history, place);
    return place;
}

void FitsWriter::write_pixels(const ImageArray& pixels, LONGLONG first, const std::string& place,
                              int bitpix) {
    if (bitpix == -32) {
        if (!to_floats(pixels))
            throw FloatRangeError("a pixel is beyond the range of a float (BITPIX -32)", place, 0,
                                  "BITPIX");
        write_floats(first, place);
        return;
    }
    if (bitpix > 0 && !pixels.isFinite().all())
        throw Error("integer BITPIX cannot hold NaN or infinite pixels", place, 0, "BITPIX");
    // Row-major ImageArray = FITS order; cfitsio converts doubles to BITPIX and reports
    // NUM_OVERFLOW for integer pixels out of range.
    int status = 0;
    fits_write_img(impl_->f, TDOUBLE, first, LONGLONG(pixels.size()),
                   const_cast<double*>(pixels.data()), &status);
    fits_check(status, place);
}

bool FitsWriter::to_floats(const ImageArray& pixels) {
    impl_->floats.resize(std::size_t(pixels.size()));
    return float_bytes(pixels.data(), impl_->floats.size(), impl_->floats.data());
}

// The converted pixels (impl_->floats) at their place in the data unit, as cfitsio's own
// writer puts them (ffmbyt and ffpbyt, with the header closed first).
void FitsWriter::write_floats(LONGLONG first, const std::string& place) {
    int status = 0;
    LONGLONG header = 0, data = 0, end = 0;
    fits_set_hdustruc(impl_->f, &status);
    fits_get_hduaddrll(impl_->f, &header, &data, &end, &status);
    ffmbyt(impl_->f, data + (first - 1) * LONGLONG(sizeof(float)), cfitsio_ignore_eof, &status);
    ffpbyt(impl_->f, LONGLONG(impl_->floats.size() * sizeof(float)), impl_->floats.data(), &status);
    fits_check(status, place);
}

void FitsWriter::write_image(const ImageArray& image, const FitsImageSpec& spec) {
    // BITPIX −32 keeps files small, but a float cannot hold every double: the inverse variance
    // of an image in physical units (σ ~ 1e−21 erg/s/cm²/Å: weights ~ 1e42) overflows it,
    // and a tiny σ underflows. Such an HDU is written as −64 instead, so no pixel is lost.
    // The conversion is also the check: one pass.
    if (spec.bitpix == -32 && to_floats(image)) {
        write_floats(1, start_hdu(long(image.rows()), long(image.cols()), -32, spec));
        return;
    }
    const int bitpix = spec.bitpix == -32 ? -64 : spec.bitpix;
    const std::string place = start_hdu(long(image.rows()), long(image.cols()), bitpix, spec);
    write_pixels(image, 1, place, bitpix);
}

void FitsWriter::begin_image(long ny, long nx, const FitsImageSpec& spec) {
    impl_->open_place = start_hdu(ny, nx, spec.bitpix, spec);
    impl_->open_nx = nx;
    impl_->open_bitpix = spec.bitpix;
    impl_->open_rows_left = ny;
    impl_->next_element = 1;
}

void FitsWriter::write_rows(const ImageArray& rows) {
    require(impl_ && impl_->f && rows.cols() == impl_->open_nx &&
                rows.rows() <= impl_->open_rows_left,
            "FitsWriter: rows beyond the image begun");
    // Without the whole image the HDU cannot be promoted to −64 any more: write_pixels
    // refuses (FloatRangeError) before writing anything.
    write_pixels(rows, impl_->next_element, impl_->open_place, impl_->open_bitpix);
    impl_->next_element += LONGLONG(rows.size());
    impl_->open_rows_left -= long(rows.rows());
}

namespace {

// A binary-table column's rows and TFORM.
long column_rows(const FitsColumn& c) {
    return std::visit([](const auto& cells) { return long(cells.size()); }, c.cells);
}

std::string column_form(const FitsColumn& c) {
    if (std::holds_alternative<std::vector<long long>>(c.cells)) return "1K";
    if (std::holds_alternative<std::vector<double>>(c.cells)) return "1D";
    if (std::holds_alternative<std::vector<bool>>(c.cells)) return "1L";
    std::size_t width = 1;
    for (const std::string& t : std::get<std::vector<std::string>>(c.cells))
        width = std::max(width, t.size());
    return std::to_string(width) + "A";
}

}  // namespace

void FitsWriter::write_table(const std::vector<FitsColumn>& columns, const std::string& extname,
                             const std::vector<FitsKeyword>& keywords) {
    require(impl_ && impl_->f, "FitsWriter: a table after commit");
    require(impl_->open_rows_left == 0, "FitsWriter: the image begun is not finished");
    const std::string place = path() + "[" + extname + "]";
    if (columns.empty()) throw Error("a table needs at least one column", place);
    if (columns.size() > 999)
        throw Error("a FITS table holds at most 999 columns, not " +
                    std::to_string(columns.size()), place, 0, "TFIELDS");
    const long rows = column_rows(columns.front());
    std::vector<std::string> names, forms, units;
    for (const FitsColumn& c : columns) {
        if (column_rows(c) != rows)
            throw Error("columns differ in length", place, 0, c.name);
        names.push_back(c.name);
        units.push_back(c.unit);
        forms.push_back(column_form(c));
    }
    auto pointers = [](std::vector<std::string>& v) {
        std::vector<char*> p;
        for (std::string& s : v) p.push_back(s.data());
        return p;
    };
    std::vector<char*> ttype = pointers(names), tform = pointers(forms), tunit = pointers(units);
    int status = 0;
    fits_create_tbl(impl_->f, BINARY_TBL, LONGLONG(rows), int(columns.size()), ttype.data(),
                    tform.data(), tunit.data(), const_cast<char*>(extname.c_str()), &status);
    fits_check(status, place);
    for (const auto& key : keywords) write_keyword(impl_->f, key, place);
    if (rows == 0) return;
    LONGLONG offset = 0;  // the column's first byte in a row
    for (std::size_t k = 0; k < columns.size(); ++k) {
        const FitsColumn& c = columns[k];
        const int column = int(k) + 1;
        LONGLONG width = 8;
        if (const auto* v = std::get_if<std::vector<long long>>(&c.cells)) {
            fits_write_col(impl_->f, TLONGLONG, column, 1, 1, LONGLONG(v->size()),
                           const_cast<long long*>(v->data()), &status);
        } else if (const auto* v = std::get_if<std::vector<double>>(&c.cells)) {
            fits_write_col(impl_->f, TDOUBLE, column, 1, 1, LONGLONG(v->size()),
                           const_cast<double*>(v->data()), &status);
        } else if (const auto* v = std::get_if<std::vector<bool>>(&c.cells)) {
            std::vector<char> flags(v->begin(), v->end());
            fits_write_col(impl_->f, TLOGICAL, column, 1, 1, LONGLONG(flags.size()), flags.data(),
                           &status);
            width = 1;
        } else {
            // NUL-padded, as astropy and numpy strip (cfitsio's own writer pads with blanks,
            // which astropy's Table keeps): each cell's bytes at its place in the row.
            const auto& texts = std::get<std::vector<std::string>>(c.cells);
            width = LONGLONG(std::stoul(forms[k]));
            std::vector<unsigned char> cell(static_cast<std::size_t>(width));
            for (long r = 0; r < rows && status == 0; ++r) {
                std::fill(cell.begin(), cell.end(), 0);
                std::copy(texts[std::size_t(r)].begin(), texts[std::size_t(r)].end(),
                          cell.begin());
                fits_write_tblbytes(impl_->f, LONGLONG(r) + 1, offset + 1, width, cell.data(),
                                    &status);
            }
        }
        fits_check(status, place);
        offset += width;
    }
}

void FitsWriter::commit() {
    require(impl_ && impl_->f, "FitsWriter: commit twice");
    require(impl_->open_rows_left == 0, "FitsWriter: the image begun is not finished");
    int status = 0;
    fits_close_file(impl_->f, &status);  // flushes: write errors (disk full) surface here
    impl_->f = nullptr;
    fits_check(status, path());
    impl_->file.commit();
}

// ----------------------------------------------------------------------------------- stamps

std::string stamp_image_extname(const std::string& id) { return id + ".image"; }
std::string stamp_weight_extname(const std::string& id) { return id + ".weight"; }
std::string stamp_mask_extname(const std::string& id) { return id + ".mask"; }

Stamp read_stamp(FitsReader& fits, const std::string& id) {
    Stamp stamp;
    stamp.id = id;
    fits.move_to(stamp_image_extname(id));
    stamp.image = fits.read_image();
    // LTVi = 1 − (parent pixel of stamp pixel 1): IRAF's physical = logical − LTV.
    stamp.x0 = int(1 - fits.optional_int("LTV1").value_or(0));
    stamp.y0 = int(1 - fits.optional_int("LTV2").value_or(0));
    fits.move_to(stamp_weight_extname(id));
    stamp.weight = fits.read_image();
    if (stamp.weight.rows() != stamp.image.rows() || stamp.weight.cols() != stamp.image.cols())
        throw Error("weight size differs from the image's", fits.place(), 0, "NAXIS1");
    fits.move_to(stamp_mask_extname(id));
    stamp.mask = fits.read_image();
    if (stamp.mask.rows() != stamp.image.rows() || stamp.mask.cols() != stamp.image.cols())
        throw Error("mask size differs from the image's", fits.place(), 0, "NAXIS1");
    return stamp;
}

void write_stamp(FitsWriter& out, const Stamp& stamp) {
    const std::vector<FitsKeyword> origin = {{"LTV1", 1 - stamp.x0, "parent x = stamp x - LTV1"},
                                             {"LTV2", 1 - stamp.y0, "parent y = stamp y - LTV2"},
                                             {"LTM1_1", 1, "no rebinning"},
                                             {"LTM2_2", 1, "no rebinning"}};
    out.write_image(stamp.image, {stamp_image_extname(stamp.id), -32, "", {}, origin, {}});
    out.write_image(stamp.weight, {stamp_weight_extname(stamp.id), -32, "", {}, origin, {}});
    out.write_image(stamp.mask, {stamp_mask_extname(stamp.id), 8, "", {}, origin, {}});
}

}  // namespace shapesim
