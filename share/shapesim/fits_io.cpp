#include "shapesim/fits_io.hpp"
#include "shapesim/version.hpp"

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

namespace {

// The one door for cfitsio statuses (Gnuastro's gal_fits_io_error): a non-zero status becomes
// an Error with cfitsio's short text (or `instead`), the place and the keyword. cfitsio's
// message stack is cleared so it does not grow across caught errors.
void check(int status, const std::string& place, const std::string& keyword = {},
           const std::string& instead = {}) {
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

// Read a string keyword; false when absent or undefined. Throws through check() otherwise.
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
    check(status, place, key);
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
                                        std::to_string(c + 1) + " (" + key.substr(0, key.find(' ')) +
                                        ") holds byte " + std::to_string(int(b)) +
                                        ", not printable ASCII",
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
                                        std::to_string(c + 1) + " (" + key.substr(0, key.find(' ')) +
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
        check(status, path, {}, why);
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
    check(status, impl_->file);
    return count;
}

void FitsReader::move_to(int index) {
    int status = 0, type = 0;
    fits_movabs_hdu(impl_->f, index + 1, &type, &status);
    if (status != 0) {
        const std::string place = impl_->file + "[" + std::to_string(index) + "]";
        impl_->located();
        check(status, place, {},
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
        check(status, impl_->file, {}, "no HDU named '" + extname + "'");
    }
    check(status, impl_->file + "[" + extname + "]");
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
    check(status, impl_->file + "[" + extname + "]");
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
        check(status, impl_->place);
        out.push_back(std::move(info));
    }
    move_to(here);
    return out;
}

ImageSize FitsReader::image_size() {
    const std::string& place = impl_->place;
    int status = 0, type = 0, naxis = 0;
    fits_get_hdu_type(impl_->f, &type, &status);
    check(status, place);
    if (type != IMAGE_HDU) throw Error("not an image HDU (a table)", place);
    fits_get_img_dim(impl_->f, &naxis, &status);
    check(status, place, "NAXIS");
    if (naxis == 0) throw Error("image is empty (NAXIS = 0)", place, 0, "NAXIS");
    if (naxis < 2 || naxis > 9)
        throw Error("expected a 2D image, got NAXIS = " + std::to_string(naxis), place, 0, "NAXIS");
    LONGLONG naxes[9] = {0};
    fits_get_img_sizell(impl_->f, naxis, naxes, &status);
    check(status, place, "NAXIS1");
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
    check(status, impl_->place);
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
    check(status, impl_->place);
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
    check(status, impl_->place);
    return image;
}

// ------------------------------------------------------------------------------- tables

long FitsReader::table_rows() {
    int status = 0, type = 0;
    fits_get_hdu_type(impl_->f, &type, &status);
    check(status, impl_->place);
    if (type != BINARY_TBL && type != ASCII_TBL)
        throw Error("not a table (an image HDU)", impl_->place);
    LONGLONG rows = 0, header_start = 0, data_start = 0, data_end = 0;
    long row_bytes = 0;
    fits_get_num_rowsll(impl_->f, &rows, &status);
    fits_read_key(impl_->f, TLONG, "NAXIS1", &row_bytes, nullptr, &status);
    fits_get_hduaddrll(impl_->f, &header_start, &data_start, &data_end, &status);
    check(status, impl_->place);
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
    check(status, place, name);
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
    check(status, impl_->place, name);
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
    check(status, impl_->place, name);
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
        check(status, impl_->place, name);
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
    check(status, impl_->place, key);
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
    check(status, impl_->place, key);
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
    check(status, impl_->place, key);
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

// ---------------------------------------------------------------------------------- writing

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
    check(status, place, key.name);
}

void write_history(fitsfile* f, const std::vector<std::string>& lines, const std::string& place) {
    int status = 0;
    for (const auto& line : lines) fits_write_history(f, line.c_str(), &status);
    check(status, place, "HISTORY");
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
        write_keyword(f, {"PV" + std::to_string(pv.i) + "_" + std::to_string(pv.m), pv.value}, place);
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
    check(status, path);
    fits_create_img(impl_->f, BYTE_IMG, 0, nullptr, &status);
    check(status, path);
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
            const Bytes16 swapped =
                __builtin_shufflevector(bytes, bytes, 3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
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
    check(status, place);
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
    check(status, place);
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
    check(status, place);
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
    check(status, place);
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
        check(status, place);
        offset += width;
    }
}

void FitsWriter::commit() {
    require(impl_ && impl_->f, "FitsWriter: commit twice");
    require(impl_->open_rows_left == 0, "FitsWriter: the image begun is not finished");
    int status = 0;
    fits_close_file(impl_->f, &status);  // flushes: write errors (disk full) surface here
    impl_->f = nullptr;
    check(status, path());
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
