#include "shapesim/geometry.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <wcslib/wcs.h>
#include <wcslib/wcshdr.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <cmath>
#include <optional>
#include <ostream>

namespace shapesim {

namespace {

double det_cd(const WcsKeywords& w) { return w.cd1_1 * w.cd2_2 - w.cd1_2 * w.cd2_1; }

std::string trimmed(std::string s) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

// One 80-column header card "KEY     = value", as wcspih() reads them.
void card(std::string& header, const std::string& key, const std::string& value) {
    char text[81];
    std::snprintf(text, sizeof text, "%-8.8s= %-70.70s", key.c_str(), value.c_str());
    header += text;
}

std::string number(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.17G", v);
    return text;
}

std::string quoted(const std::string& s) { return "'" + s + "'"; }

// The keywords as a FITS header, exactly (every number to 17 significant digits).
std::string header_of(const WcsKeywords& w) {
    std::string h;
    card(h, "WCSAXES", "2");
    card(h, "CTYPE1", quoted(w.ctype1));
    card(h, "CTYPE2", quoted(w.ctype2));
    card(h, "CUNIT1", quoted("deg"));
    card(h, "CUNIT2", quoted("deg"));
    card(h, "CRPIX1", number(w.crpix1));
    card(h, "CRPIX2", number(w.crpix2));
    card(h, "CRVAL1", number(w.crval1));
    card(h, "CRVAL2", number(w.crval2));
    card(h, "CD1_1", number(w.cd1_1));
    card(h, "CD1_2", number(w.cd1_2));
    card(h, "CD2_1", number(w.cd2_1));
    card(h, "CD2_2", number(w.cd2_2));
    card(h, "RADESYS", quoted(w.radesys));
    if (w.radesys == "FK5" || w.radesys == "FK4")
        card(h, "EQUINOX", w.radesys == "FK5" ? "2000.0" : "1950.0");
    if (w.lonpole) card(h, "LONPOLE", number(*w.lonpole));
    if (w.latpole) card(h, "LATPOLE", number(*w.latpole));
    for (const auto& pv : w.pv)
        card(h, "PV" + std::to_string(pv.i) + "_" + std::to_string(pv.m), number(pv.value));
    if (w.has_sip()) {
        card(h, "A_ORDER", std::to_string(w.sip_order));
        card(h, "B_ORDER", std::to_string(w.sip_order));
        for (const auto& [prefix, terms] : {std::pair{"A", &w.sip_a}, std::pair{"B", &w.sip_b}})
            for (std::size_t p = 0; p < terms->size(); ++p)
                for (std::size_t q = 0; q < (*terms)[p].size(); ++q)
                    if ((*terms)[p][q] != 0.0) {
                        const std::string key =
                            std::string(prefix) + "_" + std::to_string(p) + "_" + std::to_string(q);
                        card(h, key, number((*terms)[p][q]));
                    }
    }
    return h;
}

// wcslib's words for a failed call: its status text. (Its longer messages, wcserr_enable(),
// leak an allocation per error in Debian's wcslib 7.12 under LeakSanitizer.)
std::string wcslib_message(int status) {
    if (status > 0 && status < 14) return std::string("wcslib: ") + wcs_errmsg[status];
    return "wcslib: status " + std::to_string(status);
}

// The field (keyword) an error from wcslib is most likely about.
const char* suspect_keyword(int status) {
    switch (status) {
        case WCSERR_SINGULAR_MTX: return "CD1_1";
        case WCSERR_BAD_PARAM: return "PV2_1";
        default: return "CTYPE1";
    }
}

void check_keywords(const WcsKeywords& w) {
    for (const auto* c : {&w.sip_a, &w.sip_b})
        for (const auto& row : *c)
            for (double v : row)
                if (!std::isfinite(v)) throw Error("SIP term is not finite", {}, 0, "A_ORDER");
    for (double v : {w.crpix1, w.crpix2, w.crval1, w.crval2, w.cd1_1, w.cd1_2, w.cd2_1, w.cd2_2})
        if (!std::isfinite(v)) throw Error("WCS value is not finite", {}, 0, "CD1_1");
    for (const auto& pv : w.pv)
        if (!std::isfinite(pv.value))
            throw Error("is not finite", {}, 0,
                        "PV" + std::to_string(pv.i) + "_" + std::to_string(pv.m));
    if (!(std::abs(w.crval2) <= 90.0))
        throw Error("must be within [-90, 90] degrees", {}, 0, "CRVAL2");
    if (det_cd(w) == 0.0) throw Error("CD matrix is singular", {}, 0, "CD1_1");
    const std::string c1 = trimmed(w.ctype1), c2 = trimmed(w.ctype2);
    if (c1.size() < 8 || c1.compare(0, 5, "RA---") != 0)
        throw Error("expected RA--- and a projection code (e.g. RA---TAN; RA first), got '" +
                        w.ctype1 + "'",
                    {}, 0, "CTYPE1");
    const bool sip_ctype = c1.size() == 12 && c1.substr(8) == "-SIP";
    if (sip_ctype != w.has_sip())
        throw Error(w.has_sip() ? "SIP terms need CTYPEs ending in -SIP, got '" + w.ctype1 + "'"
                                : "'" + w.ctype1 + "' needs the SIP terms (A_ORDER, B_ORDER)",
                    {}, 0, "CTYPE1");
    if (sip_ctype && c1.substr(5, 3) != "TAN")
        throw Error("SIP distortion goes with TAN only, got '" + w.ctype1 + "'", {}, 0, "CTYPE1");
    if (c2.size() < 8 || c2.compare(0, 5, "DEC--") != 0 || c2.substr(5) != c1.substr(5))
        throw Error("expected DEC--" + c1.substr(std::min<std::size_t>(5, c1.size())) +
                        " (the projection of CTYPE1), got '" + w.ctype2 + "'",
                    {}, 0, "CTYPE2");
}

}  // namespace

std::string WcsKeywords::projection() const {
    const std::string c = trimmed(ctype1);
    return c.size() >= 8 ? c.substr(5, 3) : std::string();
}

// wcslib's state for one WCS. Distortions keep scratch space in it, so calls take turns.
struct Wcs::Engine {
    mutable wcsprm w{};
    mutable std::mutex turn;
    bool tan = false;  ///< TAN (any distortion): sky_to_pixel refuses θ ≤ 0

    explicit Engine(const WcsKeywords& keywords) {
        // wcspih's header parser is not documented as reentrant: one header at a time.
        static std::mutex parsing;
        const std::lock_guard<std::mutex> lock(parsing);
        std::string header = header_of(keywords);
        int rejected = 0, count = 0;
        wcsprm* parsed = nullptr;
        int status = wcspih(header.data(), int(header.size() / 80), WCSHDR_all, 0, &rejected,
                            &count, &parsed);
        if (status != 0 || count < 1) {
            if (parsed) wcsvfree(&count, &parsed);
            const std::string why = "status " + std::to_string(status);
            throw Error("wcslib cannot read the WCS keywords (" + why + ")", {}, 0, "CTYPE1");
        }
        w.flag = -1;
        status = wcssub(1, parsed, nullptr, nullptr, &w);
        wcsvfree(&count, &parsed);
        if (status == 0) status = wcsset(&w);
        if (status != 0) {
            wcsfree(&w);
            throw Error(wcslib_message(status), {}, 0, suspect_keyword(status));
        }
        if (w.naxis != 2 || w.lng != 0 || w.lat != 1) {
            wcsfree(&w);
            throw Error("not a celestial WCS with RA first and Dec second", {}, 0, "CTYPE1");
        }
        tan = keywords.projection() == "TAN";
    }
    ~Engine() { wcsfree(&w); }
    Engine(const Engine&) = delete;
    Engine& operator=(const Engine&) = delete;
};

Wcs::Wcs() : Wcs(WcsKeywords{}) {}

Wcs::Wcs(WcsKeywords keywords) : keywords_(std::move(keywords)) {
    check_keywords(keywords_);
    engine_ = std::make_shared<const Engine>(keywords_);
}

SkyPosition Wcs::pixel_to_sky(double x, double y) const {
    const double pixel[2] = {x, y};
    double image[2], phi, theta, world[2];
    int stat = 0, status;
    {
        const std::lock_guard<std::mutex> lock(engine_->turn);
        status = wcsp2s(&engine_->w, 1, 2, pixel, image, &phi, &theta, world, &stat);
    }
    if (status != 0)
        throw Error("pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                    ") is outside the projection's domain");
    double ra = std::fmod(world[0], 360.0);
    if (ra < 0.0) ra += 360.0;
    return {ra, world[1]};
}

PixelPosition Wcs::sky_to_pixel(double ra, double dec) const {
    const double world[2] = {ra, dec};
    double phi, theta, image[2], pixel[2];
    int stat = 0, status;
    {
        const std::lock_guard<std::mutex> lock(engine_->turn);
        status = wcss2p(&engine_->w, 1, 2, world, &phi, &theta, image, pixel, &stat);
    }
    // TAN reaches only the hemisphere about its reference point (θ > 0).
    if (status != 0 || (engine_->tan && !(theta > 0.0)))
        throw Error("(" + std::to_string(ra) + ", " + std::to_string(dec) +
                    ") is 90 degrees or more from the WCS reference point, or beyond the "
                    "projection's reach");
    return {pixel[0], pixel[1]};
}

double Wcs::pixel_scale_arcsec() const { return std::sqrt(std::abs(det_cd(keywords_))) * 3600.0; }

Wcs Wcs::cutout(long x0, long y0) const {
    WcsKeywords w = keywords_;
    w.crpix1 -= double(x0 - 1);
    w.crpix2 -= double(y0 - 1);
    return Wcs(std::move(w));
}

Wcs Wcs::binned(int factor) const {
    require(factor >= 1, "Wcs::binned: the factor must be at least 1");
    WcsKeywords w = keywords_;
    const double b = factor;
    w.crpix1 = (w.crpix1 + 0.5 * (b - 1.0)) / b;
    w.crpix2 = (w.crpix2 + 0.5 * (b - 1.0)) / b;
    w.cd1_1 *= b, w.cd1_2 *= b, w.cd2_1 *= b, w.cd2_2 *= b;
    if (w.has_sip()) {
        w.sip_order = 0;
        w.sip_a.clear();
        w.sip_b.clear();
        w.ctype1 = trimmed(w.ctype1).substr(0, 8);
        w.ctype2 = trimmed(w.ctype2).substr(0, 8);
    }
    return Wcs(std::move(w));
}

Wcs tan_wcs(double ra, double dec, double pixel_scale_arcsec, double crpix1, double crpix2,
            double rotation_deg) {
    require(pixel_scale_arcsec > 0.0, "tan_wcs: pixel scale must be > 0");
    WcsKeywords w;
    w.crval1 = ra;
    w.crval2 = dec;
    w.crpix1 = crpix1;
    w.crpix2 = crpix2;
    // CDELT1 = −s (east left), CDELT2 = s (north up), rotated as FITS CROTA2 (read_cd).
    const double s = pixel_scale_arcsec / 3600.0, rho = rotation_deg * degree;
    w.cd1_1 = -s * std::cos(rho);
    w.cd1_2 = -s * std::sin(rho);
    w.cd2_1 = -s * std::sin(rho);
    w.cd2_2 = s * std::cos(rho);
    return Wcs(std::move(w));
}

double FieldGeometry::area_arcmin2() const {
    return double(nx) * double(ny) * pixel_scale * pixel_scale / 3600.0;
}

FieldGeometry make_field(double width_arcmin, double height_arcmin, double pixel_scale,
                         double ra, double dec) {
    require(pixel_scale > 0.0 && std::isfinite(pixel_scale), "the pixel scale must be > 0");
    const double nx = std::round(width_arcmin * 60.0 / pixel_scale);
    const double ny = std::round(height_arcmin * 60.0 / pixel_scale);
    if (!(nx >= 1.0 && ny >= 1.0 && nx <= 1e9 && ny <= 1e9))
        throw Error("the field is not a sensible number of pixels (" + std::to_string(nx) +
                    " x " + std::to_string(ny) + ")");
    FieldGeometry g;
    g.nx = int(nx);
    g.ny = int(ny);
    g.pixel_scale = pixel_scale;
    g.wcs = tan_wcs(ra, dec, pixel_scale, 0.5 + nx / 2.0, 0.5 + ny / 2.0);
    return g;
}

bool Tile::reaches(double x, double y, double radius) const {
    // Distance from (x, y) to the window's area [x0 − ½, x1 + ½] × [y0 − ½, y1 + ½].
    const double dx = std::max({double(x0) - 0.5 - x, 0.0, x - double(x1) - 0.5});
    const double dy = std::max({double(y0) - 0.5 - y, 0.0, y - double(y1) - 0.5});
    return dx * dx + dy * dy <= radius * radius;
}

bool Tile::owns(double x, double y) const {
    return x >= double(x0) - 0.5 && x < double(x1) + 0.5 && y >= double(y0) - 0.5 &&
           y < double(y1) + 0.5;
}

std::vector<Tile> tile_grid(long field_nx, long field_ny, long width, long height) {
    if (width < 1 || height < 1) throw Error("tile sides must be at least 1 pixel");
    std::vector<Tile> tiles;
    for (long y0 = 1; y0 <= field_ny; y0 += height)
        for (long x0 = 1; x0 <= field_nx; x0 += width)
            tiles.push_back(
                {x0, y0, std::min(x0 + width - 1, field_nx), std::min(y0 + height - 1, field_ny)});
    return tiles;
}

std::vector<TileWindow> tile_windows(long field_nx, long field_ny, long side, long margin) {
    if (margin < 0) throw Error("a tile margin cannot be negative");
    std::vector<TileWindow> windows;
    for (const Tile& core : tile_grid(field_nx, field_ny, side, side))
        windows.push_back({core, {std::max(core.x0 - margin, 1L), std::max(core.y0 - margin, 1L),
                                  std::min(core.x1 + margin, field_nx),
                                  std::min(core.y1 + margin, field_ny)}});
    return windows;
}

void write_tile_grid(std::ostream& out, const std::string& name, long field_nx, long field_ny,
                     long width, long height) {
    for (const Tile& t : tile_grid(field_nx, field_ny, width, height))
        out << (t.x0 - 1) / width << ' ' << (t.y0 - 1) / height << ' ' << t.x0 << ' ' << t.y0
            << ' ' << t.x1 << ' ' << t.y1 << '\n';
    out.flush();
    if (!out) throw Error("cannot write the tile grid", name);
}

}  // namespace shapesim
