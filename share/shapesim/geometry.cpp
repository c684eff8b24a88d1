#include "shapesim/geometry.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <ostream>

namespace shapesim {

namespace {

double det_cd(const Wcs& w) { return w.cd1_1 * w.cd2_2 - w.cd1_2 * w.cd2_1; }

std::string trimmed(std::string s) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

double sip_sum(const std::vector<std::vector<double>>& c, double u, double v) {
    double sum = 0.0, up = 1.0;
    for (std::size_t p = 0; p < c.size(); ++p, up *= u) {
        double vq = 1.0;
        for (std::size_t q = 0; p + q < c.size(); ++q, vq *= v) sum += c[p][q] * up * vq;
    }
    return sum;
}
}  // namespace

std::pair<double, double> Wcs::distort(double u, double v) const {
    if (!has_sip()) return {u, v};
    return {u + sip_sum(sip_a, u, v), v + sip_sum(sip_b, u, v)};
}

SkyPosition Wcs::pixel_to_sky(double x, double y) const {
    const auto [dx, dy] = distort(x - crpix1, y - crpix2);
    const double xi = (cd1_1 * dx + cd1_2 * dy) * degree;
    const double eta = (cd2_1 * dx + cd2_2 * dy) * degree;
    const double dec0 = crval2 * degree;
    const double denom = std::cos(dec0) - eta * std::sin(dec0);
    double ra = crval1 + std::atan2(xi, denom) / degree;
    const double dec = std::atan2(eta * std::cos(dec0) + std::sin(dec0), std::hypot(xi, denom));
    ra = std::fmod(ra, 360.0);
    if (ra < 0.0) ra += 360.0;
    return {ra, dec / degree};
}

PixelPosition Wcs::sky_to_pixel(double ra, double dec) const {
    const double dra = (ra - crval1) * degree, d = dec * degree, d0 = crval2 * degree;
    const double cos_c = std::sin(d) * std::sin(d0) + std::cos(d) * std::cos(d0) * std::cos(dra);
    if (!(cos_c > 0.0))
        throw Error("(" + std::to_string(ra) + ", " + std::to_string(dec) +
                    ") is 90 degrees or more from the WCS reference point");
    const double xi = std::cos(d) * std::sin(dra) / cos_c / degree;
    const double eta =
        (std::cos(d0) * std::sin(d) - std::sin(d0) * std::cos(d) * std::cos(dra)) / cos_c / degree;
    // Invert the 2×2 CD matrix (validated non-singular), then the distortion: Newton on
    // distort(u, v) = (u′, v′), from (u′, v′); SIP terms are small, so it converges in a few
    // steps (the Jacobian by central differences of 1e−3 pixel, exact for the quadratic part).
    const double det = det_cd(*this);
    const double ud = (cd2_2 * xi - cd1_2 * eta) / det, vd = (-cd2_1 * xi + cd1_1 * eta) / det;
    double u = ud, v = vd;
    for (int step = 0; has_sip() && step < 50; ++step) {
        const auto [fu, fv] = distort(u, v);
        const double ru = fu - ud, rv = fv - vd;
        if (std::hypot(ru, rv) < 1e-10) break;
        constexpr double h = 1e-3;
        const auto [au, av] = distort(u + h, v);
        const auto [bu, bv] = distort(u - h, v);
        const auto [cu, cv] = distort(u, v + h);
        const auto [du, dv] = distort(u, v - h);
        const double j11 = (au - bu) / (2 * h), j21 = (av - bv) / (2 * h);
        const double j12 = (cu - du) / (2 * h), j22 = (cv - dv) / (2 * h);
        const double jdet = j11 * j22 - j12 * j21;
        if (!(std::abs(jdet) > 1e-12)) break;
        u -= (j22 * ru - j12 * rv) / jdet;
        v -= (-j21 * ru + j11 * rv) / jdet;
    }
    return {crpix1 + u, crpix2 + v};
}

double Wcs::pixel_scale_arcsec() const { return std::sqrt(std::abs(det_cd(*this))) * 3600.0; }

void Wcs::validate() const {
    const std::string suffix = has_sip() ? "-SIP" : "";
    if (trimmed(ctype1) != "RA---TAN" + suffix)
        throw Error("expected 'RA---TAN" + suffix + "' (TAN, with SIP or without), got '" +
                        ctype1 + "'",
                    {}, 0, "CTYPE1");
    if (trimmed(ctype2) != "DEC--TAN" + suffix)
        throw Error("expected 'DEC--TAN" + suffix + "', got '" + ctype2 + "'", {}, 0, "CTYPE2");
    for (const auto* c : {&sip_a, &sip_b})
        for (const auto& row : *c)
            for (double v : row)
                if (!std::isfinite(v)) throw Error("SIP term is not finite", {}, 0, "A_ORDER");
    for (double v : {crpix1, crpix2, crval1, crval2, cd1_1, cd1_2, cd2_1, cd2_2})
        if (!std::isfinite(v)) throw Error("WCS value is not finite", {}, 0, "CD1_1");
    if (!(std::abs(crval2) <= 90.0))
        throw Error("must be within [-90, 90] degrees", {}, 0, "CRVAL2");
    if (det_cd(*this) == 0.0) throw Error("CD matrix is singular", {}, 0, "CD1_1");
}

Wcs Wcs::cutout(long x0, long y0) const {
    Wcs w = *this;
    w.crpix1 -= double(x0 - 1);
    w.crpix2 -= double(y0 - 1);
    return w;
}

Wcs tan_wcs(double ra, double dec, double pixel_scale_arcsec, double crpix1, double crpix2,
            double rotation_deg) {
    require(pixel_scale_arcsec > 0.0, "tan_wcs: pixel scale must be > 0");
    Wcs w;
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
    w.validate();
    return w;
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
    return x >= double(x0) - 0.5 && x < double(x1) + 0.5 && y >= double(y0) - 0.5 && y < double(y1) + 0.5;
}

std::vector<Tile> tile_grid(long field_nx, long field_ny, long width, long height) {
    if (width < 1 || height < 1) throw Error("tile sides must be at least 1 pixel");
    std::vector<Tile> tiles;
    for (long y0 = 1; y0 <= field_ny; y0 += height)
        for (long x0 = 1; x0 <= field_nx; x0 += width)
            tiles.push_back({x0, y0, std::min(x0 + width - 1, field_nx), std::min(y0 + height - 1, field_ny)});
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
