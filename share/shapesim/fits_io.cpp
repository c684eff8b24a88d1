// FITS reading: FitsReader (images, regions, tables, keywords, HDUs by name or number) and the
// header checks made before cfitsio parses a file; writing is fits_write.cpp.
#include "shapesim/fits_io.hpp"

#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"

#include <fitsio.h>
#include <strings.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sys/stat.h>
#include <variant>


namespace shapesim {

using detail::fits_check;

// The one door for cfitsio statuses (Gnuastro's gal_fits_io_error): a non-zero status becomes
// an Error with cfitsio's short text (or `instead`), the place and the keyword. cfitsio's
// message stack is cleared so it does not grow across caught errors.
void detail::fits_check(int status, const std::string& place, const std::string& keyword,
                        const std::string& instead) {
    if (status == 0) return;
    char text[FLEN_STATUS] = "";
    fits_get_errstatus(status, text);
    fits_clear_errmsg();
    std::string message = instead.empty() ? std::string(text) : instead;
    // cfitsio's texts for a short read do not say why; the usual causes do.
    if (instead.empty() && (status == END_OF_FILE || status == READ_ERROR))
        message += " (truncated, or not a FITS file?)";
    else if (instead.empty() && (status == UNKNOWN_REC || status == NO_SIMPLE))
        message += " (not a FITS file?)";
    throw Error(message, place, 0, keyword);
}

namespace {

std::string trim_right(std::string s) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

// The file name without cfitsio's `[...]` specifiers, for messages.
std::string root_name(const std::string& path) {
    char root[FLEN_FILENAME] = "";
    int status = 0;
    fits_parse_rootname(const_cast<char*>(path.c_str()), root, &status);
    fits_clear_errmsg();
    return status == 0 && root[0] ? std::string(root) : path;
}

// Read a string keyword; false when absent or undefined. Throws through fits_check() otherwise.
bool read_string_key(fitsfile* f, const std::string& key, const std::string& place,
                     std::string& out) {
    char* value = nullptr;
    int status = 0;
    fits_read_key_longstr(f, key.c_str(), &value, nullptr, &status);
    if (status == 0) out = trim_right(value);
    int free_status = 0;  // cfitsio calls do nothing under a non-zero status: use a fresh one
    if (value) fits_free_memory(value, &free_status);
    if (status == KEY_NO_EXIST || status == VALUE_UNDEFINED) {
        fits_clear_errmsg();
        return false;
    }
    fits_check(status, place, key);
    return true;
}

}  // namespace

// ---------------------------------------------------------------------------------- reading

struct FitsReader::Impl {
    fitsfile* f = nullptr;
    std::string file, place;
    int index = 0;

    ~Impl() {
        int status = 0;
        if (f) fits_close_file(f, &status);
        fits_clear_errmsg();
    }
    // Recompute the current HDU's index and place after every move.
    void located() {
        int number = 1;
        fits_get_hdu_num(f, &number);
        index = number - 1;
        std::string extname;
        if (read_string_key(f, "EXTNAME", file, extname) && !extname.empty())
            place = file + "[" + extname + "]";
        else
            place = index == 0 ? file : file + "[" + std::to_string(index) + "]";
    }
};

namespace {

// An integer card value (`KEY     =                  123 / …`), or `fallback`.
long long card_integer(const char* card, long long fallback) {
    char* end = nullptr;
    const std::string value(card + 10, 70);
    const long long v = std::strtoll(value.c_str(), &end, 10);
    return end == value.c_str() ? fallback : v;
}

// cfitsio trusts a header's cards to be printable ASCII, as the standard requires: a control or
// 8-bit byte in a table's or an array's layout keywords can overflow its buffers while the
// file is opened (a fortify abort in ffgtbp on a TTYPE, a 10^16-byte calloc on a NAXIS2; both
// found by fuzzing). Every header of a local, uncompressed file is read first, the data units
// skipped by their declared size, and those cards checked; whatever cannot be followed (short,
// gzip, a URL, random groups) is left to cfitsio, which reports it.
void check_header_bytes(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return;
    in.seekg(0, std::ios::end);
    const long long size = in.tellg();
    char block[2880];
    long long offset = 0;
    for (int hdu = 0; offset < size && hdu < 100000; ++hdu) {
        long long bitpix = 8, naxis = 0, pcount = 0, gcount = 1, product = 1;
        bool unsized = false;  // a size this walk does not follow: check this header, then stop
        for (bool end = false; !end;) {
            in.seekg(offset);
            in.read(block, sizeof block);
            // A file that ends inside a header block: cfitsio still reads the cards it holds
            // (a crash found by fuzzing), so they are checked too, the rest taken as blanks.
            const std::streamsize got = in.gcount();
            if (got <= 0) return;
            if (got < std::streamsize(sizeof block)) {
                std::memset(block + got, ' ', sizeof block - std::size_t(got));
                in.clear();
                unsized = true;  // nothing follows: this header is the walk's last
            }
            if (offset == 0 && (unsigned char)block[0] == 0x1f && (unsigned char)block[1] == 0x8b)
                return;  // gzip: cfitsio inflates it
            // After the last HDU: whatever follows is not a header (cfitsio ignores it too).
            if (hdu > 0 && product == 1 && std::strncmp(block, "XTENSION=", 9) != 0) return;
            offset += long(sizeof block);
            for (int c = 0; c < 36 && !end; ++c) {
                const char* card = block + 80 * c;
                const std::string key(card, 8);
                // The cards cfitsio lays a table or an array out by (real headers carry stray
                // control bytes elsewhere, e.g. a newline in TinyTim's CREATED, harmlessly).
                const bool structural =
                    key.compare(0, 5, "NAXIS") == 0 || key == "BITPIX  " || key == "PCOUNT  " ||
                    key == "GCOUNT  " || key == "XTENSION" || key == "TFIELDS " ||
                    key == "THEAP   " || key.compare(0, 5, "TFORM") == 0 ||
                    key.compare(0, 5, "TTYPE") == 0 || key.compare(0, 5, "TUNIT") == 0 ||
                    key.compare(0, 5, "TBCOL") == 0 || key.compare(0, 4, "TDIM") == 0 ||
                    key.compare(0, 5, "TNULL") == 0 || key.compare(0, 5, "TSCAL") == 0 ||
                    key.compare(0, 5, "TZERO") == 0 || key.compare(0, 5, "TDISP") == 0;
                for (int k = 0; k < 80 && structural; ++k) {
                    const unsigned char b = (unsigned char)card[k];
                    if (b < 32 || b > 126)
                        throw Error("not a FITS file: header " + std::to_string(hdu) + ", card " +
                                        std::to_string(c + 1) + " (" +
                                        key.substr(0, key.find(' ')) + ") holds byte " +
                                        std::to_string(int(b)) + ", not printable ASCII",
                                    file);
                }
                if (key == "END     ") end = true;
                if (card[8] != '=') continue;
                // A text-valued layout card must hold a quoted string: cfitsio copies an
                // unquoted value of 70 characters into a 70-byte column name (a fortify abort
                // in ffgtbp on `TTYPE6  = IIII…`, found by fuzzing).
                const bool text = key == "XTENSION" || key.compare(0, 5, "TTYPE") == 0 ||
                                  key.compare(0, 5, "TFORM") == 0 ||
                                  key.compare(0, 5, "TUNIT") == 0 ||
                                  key.compare(0, 5, "TDISP") == 0 || key.compare(0, 4, "TDIM") == 0;
                if (text) {
                    int k = 10;
                    while (k < 80 && card[k] == ' ') ++k;
                    if (k < 80 && card[k] != '\'')
                        throw Error("not a FITS file: header " + std::to_string(hdu) + ", card " +
                                        std::to_string(c + 1) + " (" +
                                        key.substr(0, key.find(' ')) +
                                        ") holds an unquoted value where the standard asks for a "
                                        "quoted string",
                                    file);
                }
                if (key == "BITPIX  ") bitpix = card_integer(card, 8);
                else if (key == "NAXIS   ") naxis = card_integer(card, 0);
                else if (key == "PCOUNT  ") pcount = card_integer(card, 0);
                else if (key == "GCOUNT  ") gcount = card_integer(card, 1);
                else if (key.compare(0, 5, "NAXIS") == 0 && key[5] >= '0' && key[5] <= '9') {
                    const long long n = card_integer(card, -1);
                    // Random groups (NAXIS1 = 0), a value this reader cannot parse and sizes
                    // past 2^50 bytes: left to cfitsio, once this header's cards are checked.
                    if (n <= 0 || product > (1LL << 50) / n) unsized = true;
                    else product *= n;
                }
            }
        }
        if (unsized) return;
        const long long bytes_per = std::llabs(bitpix) / 8;
        if (naxis == 0) product = 0;
        if (pcount < 0 || gcount < 0 || pcount > (1LL << 50) || gcount > (1LL << 20)) return;
        const long long data = bytes_per * gcount * (pcount + product);
        offset += (data + 2879) / 2880 * 2880;
    }
}

}  // namespace

FitsReader::FitsReader(const std::string& path, FitsStart start) : impl_(std::make_unique<Impl>()) {
    impl_->file = root_name(path);
    check_header_bytes(impl_->file);
    int status = 0;
    if (start == FitsStart::first_image)
        fits_open_image(&impl_->f, path.c_str(), READONLY, &status);
    else
        fits_open_file(&impl_->f, path.c_str(), READONLY, &status);
    if (status != 0) {
        impl_->f = nullptr;  // cfitsio leaves no open file behind on failure
        // cfitsio says "could not open the named file" for every cause; the OS says which.
        struct stat st;
        std::string why;
        if (stat(impl_->file.c_str(), &st) != 0)
            why = std::string("cannot open: ") + std::strerror(errno);
        else if (S_ISDIR(st.st_mode))
            why = "cannot open: is a directory";
        fits_check(status, path, {}, why);
    }
    impl_->located();
}

FitsReader::~FitsReader() = default;
FitsReader::FitsReader(FitsReader&&) noexcept = default;
FitsReader& FitsReader::operator=(FitsReader&&) noexcept = default;

const std::string& FitsReader::file() const { return impl_->file; }
const std::string& FitsReader::place() const { return impl_->place; }
int FitsReader::hdu_index() const { return impl_->index; }

int FitsReader::hdu_count() {
    int count = 0, status = 0;
    fits_get_num_hdus(impl_->f, &count, &status);
    fits_check(status, impl_->file);
    return count;
}

void FitsReader::move_to(int index) {
    int status = 0, type = 0;
    fits_movabs_hdu(impl_->f, index + 1, &type, &status);
    if (status != 0) {
        const std::string place = impl_->file + "[" + std::to_string(index) + "]";
        impl_->located();
        fits_check(status, place, {},
              "no such HDU (the file has " + std::to_string(hdu_count()) + ", numbered from 0)");
    }
    impl_->located();
}

void FitsReader::move_to(const std::string& extname) {
    int status = 0;
    // Files are mostly read in the order they were written (stamps: image, weight, mask,
    // object after object): try the next HDU before cfitsio's search from the start, which
    // makes reading N stamps O(N²). (No HDU count: cfitsio finds it by walking to the end.)
    {
        int type = 0;
        fits_movabs_hdu(impl_->f, impl_->index + 2, &type, &status);  // 1-based: next HDU
        if (status == 0) {
            char value[FLEN_VALUE] = {};
            int key_status = 0;
            fits_read_key(impl_->f, TSTRING, "EXTNAME", value, nullptr, &key_status);
            if (key_status == 0 && strcasecmp(value, extname.c_str()) == 0) {
                impl_->located();
                return;
            }
        }
        status = 0;  // past the last HDU, or another name: search
        fits_clear_errmsg();
    }
    fits_movnam_hdu(impl_->f, ANY_HDU, const_cast<char*>(extname.c_str()), 0, &status);
    if (status == BAD_HDU_NUM) {
        impl_->located();
        fits_check(status, impl_->file, {}, "no HDU named '" + extname + "'");
    }
    fits_check(status, impl_->file + "[" + extname + "]");
    impl_->located();
}

bool FitsReader::has_hdu(const std::string& extname) {
    const int here = impl_->index;
    int status = 0;
    fits_movnam_hdu(impl_->f, ANY_HDU, const_cast<char*>(extname.c_str()), 0, &status);
    const bool found = status == 0;
    if (status == BAD_HDU_NUM) {  // absent is an answer, not an error
        status = 0;
        fits_clear_errmsg();
    }
    fits_check(status, impl_->file + "[" + extname + "]");
    move_to(here);
    return found;
}

std::vector<FitsHduInfo> FitsReader::list_hdus() {
    const int here = impl_->index, count = hdu_count();
    std::vector<FitsHduInfo> out;
    for (int index = 0; index < count; ++index) {
        move_to(index);
        FitsHduInfo info;
        info.index = index;
        read_string_key(impl_->f, "EXTNAME", impl_->place, info.extname);
        int status = 0, type = 0, naxis = 0;
        fits_get_hdu_type(impl_->f, &type, &status);
        info.is_image = type == IMAGE_HDU;
        if (info.is_image) {
            fits_get_img_dim(impl_->f, &naxis, &status);
            info.naxes.resize(naxis);
            if (naxis > 0) fits_get_img_sizell(impl_->f, naxis, info.naxes.data(), &status);
        }
        fits_check(status, impl_->place);
        out.push_back(std::move(info));
    }
    move_to(here);
    return out;
}

ImageSize FitsReader::image_size() {
    const std::string& place = impl_->place;
    int status = 0, type = 0, naxis = 0;
    fits_get_hdu_type(impl_->f, &type, &status);
    fits_check(status, place);
    if (type != IMAGE_HDU) throw Error("not an image HDU (a table)", place);
    fits_get_img_dim(impl_->f, &naxis, &status);
    fits_check(status, place, "NAXIS");
    if (naxis == 0) throw Error("image is empty (NAXIS = 0)", place, 0, "NAXIS");
    if (naxis < 2 || naxis > 9)
        throw Error("expected a 2D image, got NAXIS = " + std::to_string(naxis), place, 0, "NAXIS");
    LONGLONG naxes[9] = {0};
    fits_get_img_sizell(impl_->f, naxis, naxes, &status);
    fits_check(status, place, "NAXIS1");
    for (int k = 0; k < 2; ++k) {
        const std::string key = "NAXIS" + std::to_string(k + 1);
        if (naxes[k] <= 0) throw Error("image is empty", place, 0, key);
        if (naxes[k] > std::numeric_limits<int>::max())
            throw Error("image too large", place, 0, key);
    }
    for (int k = 2; k < naxis; ++k)  // a 2D image may carry degenerate axes (NAXIS3 = 1)
        if (naxes[k] != 1)
            throw Error("expected a 2D image, got NAXIS = " + std::to_string(naxis) + " with " +
                            "NAXIS" + std::to_string(k + 1) + " = " + std::to_string(naxes[k]),
                        place, 0, "NAXIS");
    return {int(naxes[0]), int(naxes[1])};
}

ImageArray FitsReader::read_image() {
    const ImageSize size = image_size();
    // A header may declare far more data than the file holds (a truncated download, a
    // mangled NAXIS): refuse it before allocating the declared image. (A tile-compressed
    // image's data is a table of another size; cfitsio checks its tiles as it reads them.)
    // (The last block's padding is not required: some writers omit it.)
    int status = 0, bitpix = 0, compressed = fits_is_compressed_image(impl_->f, &status);
    LONGLONG header_start = 0, data_start = 0, data_end = 0;
    fits_get_hduaddrll(impl_->f, &header_start, &data_start, &data_end, &status);
    fits_get_img_type(impl_->f, &bitpix, &status);
    fits_check(status, impl_->place);
    const LONGLONG pixel_bytes = LONGLONG(size.nx) * size.ny * (std::abs(bitpix) / 8);
    // The size cfitsio sees: a gzipped file is read into memory, uncompressed.
    const LONGLONG file_size = impl_->f->Fptr->logfilesize;
    if (!compressed && data_start + pixel_bytes > file_size)
        throw Error("truncated: the header declares " + std::to_string(pixel_bytes) +
                        " bytes of pixels, the file holds " +
                        std::to_string(std::max<LONGLONG>(0, file_size - data_start)),
                    impl_->place);
    ImageArray image = large_image(size.ny, size.nx);
    // FITS stores x fastest, rows of constant y one after another: the ImageArray layout.
    // A NaN null value makes cfitsio turn BLANK integers and NaN floats into NaN.
    double null_value = std::numeric_limits<double>::quiet_NaN();
    int any_null = 0;
    fits_read_img(impl_->f, TDOUBLE, 1, LONGLONG(size.nx) * size.ny, &null_value, image.data(),
                  &any_null, &status);
    fits_check(status, impl_->place);
    return image;
}

ImageArray FitsReader::read_region(long x0, long y0, long nx, long ny) {
    const ImageSize size = image_size();
    if (nx < 1 || ny < 1 || x0 < 1 || y0 < 1 || x0 - 1 > size.nx - nx || y0 - 1 > size.ny - ny)
        throw Error("the window of " + std::to_string(nx) + "×" + std::to_string(ny) +
                        " pixels from (" + std::to_string(x0) + ", " + std::to_string(y0) +
                        ") is not within the image's " + std::to_string(size.nx) + "×" +
                        std::to_string(size.ny),
                    impl_->place);
    ImageArray image = large_image(ny, nx);
    long first[2] = {x0, y0}, last[2] = {x0 + nx - 1, y0 + ny - 1}, step[2] = {1, 1};
    double null_value = std::numeric_limits<double>::quiet_NaN();
    int any_null = 0, status = 0;
    fits_read_subset(impl_->f, TDOUBLE, first, last, step, &null_value, image.data(), &any_null,
                     &status);
    fits_check(status, impl_->place);
    return image;
}

// ------------------------------------------------------------------------------- tables

long FitsReader::table_rows() {
    int status = 0, type = 0;
    fits_get_hdu_type(impl_->f, &type, &status);
    fits_check(status, impl_->place);
    if (type != BINARY_TBL && type != ASCII_TBL)
        throw Error("not a table (an image HDU)", impl_->place);
    LONGLONG rows = 0, header_start = 0, data_start = 0, data_end = 0;
    long row_bytes = 0;
    fits_get_num_rowsll(impl_->f, &rows, &status);
    fits_read_key(impl_->f, TLONG, "NAXIS1", &row_bytes, nullptr, &status);
    fits_get_hduaddrll(impl_->f, &header_start, &data_start, &data_end, &status);
    fits_check(status, impl_->place);
    // As read_image(): a mangled NAXIS2 must not make a reader allocate its declared rows.
    const LONGLONG file_size = impl_->f->Fptr->logfilesize;
    if (rows < 0 || row_bytes < 0 ||
        (row_bytes > 0 && rows > (file_size - data_start) / row_bytes))
        throw Error("truncated: the header declares " + std::to_string(rows) + " rows of " +
                        std::to_string(row_bytes) + " bytes, the file holds " +
                        std::to_string(std::max<LONGLONG>(0, file_size - data_start)),
                    impl_->place);
    return long(rows);
}

namespace {

// The column number of `name` in f's current table (case-insensitive, no wildcards matter in
// the names we ask for), and its type code and repeat count; Error naming the column.
int column_of(fitsfile* f, const std::string& name, const std::string& place, int& type,
              long& repeat) {
    int status = 0, number = 0;
    long width = 0;
    fits_get_colnum(f, CASEINSEN, const_cast<char*>(name.c_str()), &number, &status);
    if (status == COL_NOT_FOUND) {
        fits_clear_errmsg();
        throw Error("no column " + name + " in the table", place, 0, name);
    }
    if (status == COL_NOT_UNIQUE) {
        fits_clear_errmsg();
        throw Error("more than one column named " + name, place, 0, name);
    }
    fits_get_coltype(f, number, &type, &repeat, &width, &status);
    fits_check(status, place, name);
    return number;
}

// Column `name` of the current table, which must be numeric: its number and values per row.
int numeric_column(fitsfile* f, const std::string& name, const std::string& place, long& repeat) {
    int type = 0;
    const int number = column_of(f, name, place, type, repeat);
    if (type == TSTRING || type == TLOGICAL || type == TBIT)
        throw Error("column " + name + " is not numeric", place, 0, name);
    return number;
}

}  // namespace

bool FitsReader::has_column(const std::string& name) {
    int status = 0, number = 0;
    fits_get_colnum(impl_->f, CASEINSEN, const_cast<char*>(name.c_str()), &number, &status);
    fits_clear_errmsg();
    return status == 0;
}

bool FitsReader::column_is_text(const std::string& name) {
    int type = 0;
    long repeat = 0;
    column_of(impl_->f, name, impl_->place, type, repeat);
    return type == TSTRING;
}

std::vector<double> FitsReader::read_column(const std::string& name) {
    const long rows = table_rows();
    long repeat = 0;
    const int number = numeric_column(impl_->f, name, impl_->place, repeat);
    if (repeat != 1)
        throw Error("column " + name + " holds " + std::to_string(repeat) +
                        " values per row, not one",
                    impl_->place, 0, name);
    std::vector<double> values(std::size_t(rows), 0.0);
    double null_value = std::numeric_limits<double>::quiet_NaN();
    int any_null = 0, status = 0;
    if (rows > 0)
        fits_read_col(impl_->f, TDOUBLE, number, 1, 1, rows, &null_value, values.data(),
                      &any_null, &status);
    fits_check(status, impl_->place, name);
    return values;
}

std::vector<double> FitsReader::read_cell(const std::string& name, long row, long max_values) {
    const long rows = table_rows();
    long repeat = 0;
    const int number = numeric_column(impl_->f, name, impl_->place, repeat);
    if (row < 1 || row > rows)
        throw Error("no row " + std::to_string(row) + " (the table has " + std::to_string(rows) +
                        ")",
                    impl_->place, 0, name);
    if (repeat > max_values)
        throw Error("column " + name + " holds " + std::to_string(repeat) +
                        " values per row, more than " + std::to_string(max_values),
                    impl_->place, 0, name);
    std::vector<double> values(std::size_t(repeat), 0.0);
    double null_value = std::numeric_limits<double>::quiet_NaN();
    int any_null = 0, status = 0;
    if (repeat > 0)
        fits_read_col(impl_->f, TDOUBLE, number, row, 1, repeat, &null_value, values.data(),
                      &any_null, &status);
    fits_check(status, impl_->place, name);
    return values;
}

std::vector<std::string> FitsReader::read_text_column(const std::string& name) {
    const long rows = table_rows();
    int type = 0;
    long repeat = 0;
    const int number = column_of(impl_->f, name, impl_->place, type, repeat);
    if (type != TSTRING)
        throw Error("column " + name + " is not text", impl_->place, 0, name);
    // One row at a time into one buffer of the column's width: bounded by the widest entry.
    std::vector<char> buffer(std::size_t(std::max(repeat, 1L)) + 1, '\0');
    std::vector<std::string> values;
    values.reserve(std::size_t(rows));
    for (long row = 1; row <= rows; ++row) {
        char* cell = buffer.data();
        char null_text[] = "";
        int any_null = 0, status = 0;
        fits_read_col_str(impl_->f, number, row, 1, 1, null_text, &cell, &any_null, &status);
        fits_check(status, impl_->place, name);
        values.push_back(trim_right(cell));
    }
    return values;
}

bool FitsReader::has_key(const std::string& key) {
    char card[FLEN_CARD];
    int status = 0;
    fits_read_card(impl_->f, key.c_str(), card, &status);
    if (status == KEY_NO_EXIST) {
        fits_clear_errmsg();
        return false;
    }
    fits_check(status, impl_->place, key);
    return true;
}

std::optional<double> FitsReader::optional_double(const std::string& key) {
    double value = 0.0;
    int status = 0;
    fits_read_key(impl_->f, TDOUBLE, key.c_str(), &value, nullptr, &status);
    if (status == KEY_NO_EXIST || status == VALUE_UNDEFINED) {
        fits_clear_errmsg();
        return std::nullopt;
    }
    fits_check(status, impl_->place, key);
    if (!std::isfinite(value)) throw Error("not a finite number", impl_->place, 0, key);
    return value;
}

double FitsReader::required_double(const std::string& key) {
    if (auto value = optional_double(key)) return *value;
    throw Error("keyword is missing", impl_->place, 0, key);
}

std::optional<long long> FitsReader::optional_int(const std::string& key) {
    LONGLONG value = 0;
    int status = 0;
    fits_read_key(impl_->f, TLONGLONG, key.c_str(), &value, nullptr, &status);
    if (status == KEY_NO_EXIST || status == VALUE_UNDEFINED) {
        fits_clear_errmsg();
        return std::nullopt;
    }
    fits_check(status, impl_->place, key);
    return value;
}

long long FitsReader::required_int(const std::string& key) {
    if (auto value = optional_int(key)) return *value;
    throw Error("keyword is missing", impl_->place, 0, key);
}

std::optional<std::string> FitsReader::optional_string(const std::string& key) {
    std::string value;
    if (!read_string_key(impl_->f, key, impl_->place, value)) return std::nullopt;
    return value;
}

std::string FitsReader::required_string(const std::string& key) {
    if (auto value = optional_string(key)) return *value;
    throw Error("keyword is missing", impl_->place, 0, key);
}

ImageArray read_fits_image(const std::string& path) {
    FitsReader fits(path, FitsStart::first_image);
    return fits.read_image();
}

}  // namespace shapesim
