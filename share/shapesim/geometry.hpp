// Field geometry: the world coordinate system of a field and `--like IMAGE`.
//
// Pixel positions are FITS pixel coordinates (first pixel centred at (1, 1)); sky positions
// are (RA, Dec) in degrees; the CD matrix is in degrees per pixel. A Wcs is evaluated by
// wcslib (Calabretta & Greisen 2002, A&A 395, 1077): every celestial projection it knows
// (TAN, SIN, ZPN, ZEA, ARC, …) and the distortions surveys write (SIP, TPV).
// docs/library.md "World coordinates" says what is read, written and refused.
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace shapesim {

/// A sky position in degrees.
struct SkyPosition {
    double ra = 0.0, dec = 0.0;
};

/// A position in FITS pixel coordinates (first pixel centred at (1, 1)).
struct PixelPosition {
    double x = 0.0, y = 0.0;
};

/// The keywords of a celestial WCS, named after their FITS keywords: what a header holds and
/// a written image gets back. The linear part is always a CD matrix (read_wcs() converts
/// PCi_j/CDELTi and CROTA2).
struct WcsKeywords {
    double crpix1 = 0.0, crpix2 = 0.0;  ///< reference pixel (FITS coordinates)
    double crval1 = 0.0, crval2 = 0.0;  ///< reference point (RA, Dec), degrees
    double cd1_1 = 1.0, cd1_2 = 0.0;    ///< CD matrix, degrees per pixel: CDi_j
    double cd2_1 = 0.0, cd2_2 = 1.0;
    std::string ctype1 = "RA---TAN", ctype2 = "DEC--TAN";
    /// RADESYS: the frame RA/Dec are in, as read (ICRS when the header names none; the
    /// transformation does not depend on it). Written back with every WCS.
    std::string radesys = "ICRS";
    /// SIP distortion (CTYPEs end in -SIP): sip_a[p][q] = A_p_q for p + q ≤ sip_order (the
    /// larger of A_ORDER and B_ORDER; missing terms 0); empty without distortion.
    int sip_order = 0;
    std::vector<std::vector<double>> sip_a, sip_b;
    /// PVi_m cards: projection parameters (ZPN's PV2_m, …) and TPV's distortion terms.
    struct Pv {
        int i = 0, m = 0;
        double value = 0.0;
        bool operator==(const Pv& o) const { return i == o.i && m == o.m && value == o.value; }
    };
    std::vector<Pv> pv;
    std::optional<double> lonpole, latpole;  ///< LONPOLE, LATPOLE when the header sets them

    /// True when the WCS carries SIP distortion.
    bool has_sip() const { return sip_order > 0; }
    /// The projection's three-letter code: "TAN" for RA---TAN-SIP, "ZPN" for RA---ZPN.
    std::string projection() const;
};

/// A celestial WCS ready to evaluate: its keywords, checked and set up by wcslib. Immutable:
/// cutout() and binned() make new ones. Copies share the wcslib state; calls on one Wcs
/// from several threads are safe.
class Wcs {
public:
    /// The default keywords: a TAN of 1° pixels at (0, 0).
    Wcs();
    /// Throws Error (field = the keyword at fault) unless the keywords are finite, the axes
    /// are RA and Dec, det CD ≠ 0, the CTYPE ends in -SIP exactly when there are SIP terms,
    /// and wcslib accepts them.
    explicit Wcs(WcsKeywords keywords);

    const WcsKeywords& keywords() const { return keywords_; }
    /// Sky position of a pixel position.
    SkyPosition pixel_to_sky(double x, double y) const;
    /// Pixel position of a sky position; throws Error when the projection does not reach it
    /// (e.g. 90° or more from a TAN reference point).
    PixelPosition sky_to_pixel(double ra, double dec) const;
    /// Pixel scale √|det CD|, arcsec per pixel.
    double pixel_scale_arcsec() const;
    /// The WCS of a cutout whose first pixel is this one's pixel (`x0`, `y0`): CRPIX moved by
    /// (x0 − 1, y0 − 1). SIP terms are in offsets from CRPIX, so they move with it unchanged.
    Wcs cutout(long x0, long y0) const;
    /// The WCS of the field binned `factor` × `factor` (pixel (1, 1) of the binned grid covers
    /// pixels 1…factor): CRPIX and CD rescaled; SIP distortion, which is in pixel offsets, is
    /// dropped (TPV's, in degrees, is kept).
    Wcs binned(int factor) const;

private:
    struct Engine;
    WcsKeywords keywords_;
    std::shared_ptr<const Engine> engine_;
};

/// A north-up, east-left TAN WCS with square pixels: `pixel_scale_arcsec` per pixel, the sky
/// position (`ra`, `dec`) (degrees) at pixel (`crpix1`, `crpix2`), rotated by
/// `rotation_deg` degrees as FITS CROTA2 does.
Wcs tan_wcs(double ra, double dec, double pixel_scale_arcsec, double crpix1, double crpix2,
            double rotation_deg = 0.0);

/// The geometry of a field, as taken by `--like IMAGE` (DESIGN §1).
struct FieldGeometry {
    int nx = 0, ny = 0;        ///< size in pixels (NAXIS1, NAXIS2)
    double pixel_scale = 0.0;  ///< arcsec per pixel (√|det CD|)
    Wcs wcs;
    std::string bunit;         ///< BUNIT of a --like image (empty: none, or a made field)
    double saturate = 0.0;     ///< SATURATE of a --like image, image units (0: none)

    /// Area of the field in arcmin².
    double area_arcmin2() const;
};

/// A north-up field of `width` × `height` arcmin at `pixel_scale` arcsec per pixel, centred on
/// (`ra`, `dec`) degrees (CRPIX at the centre of the pixel grid). Throws Error unless the sizes
/// give between 1 and 10⁹ pixels a side.
FieldGeometry make_field(double width_arcmin, double height_arcmin, double pixel_scale,
                         double ra, double dec);

/// A window of a field's pixels, FITS coordinates, inclusive: pixels x0…x1, y0…y1.
struct Tile {
    long x0 = 1, y0 = 1, x1 = 1, y1 = 1;
    /// Whether a circle of `radius` pixels about (x, y) meets the window's pixel area.
    bool reaches(double x, double y, double radius) const;
    /// Whether (x, y) lies in the window's pixels, [x0 − ½, x1 + ½) × [y0 − ½, y1 + ½): each
    /// point of a field belongs to exactly one tile of a grid.
    bool owns(double x, double y) const;
};

/// The field cut into tiles of `width` × `height` pixels, row by row from (1, 1); the last
/// column and row of tiles take what is left. Throws Error unless both sides are ≥ 1.
std::vector<Tile> tile_grid(long field_nx, long field_ny, long width, long height);

/// A tile of an image processed piece by piece: `core`, the pixels it answers for, and
/// `window`, the pixels read for it (the core and a margin on each side, within the image).
struct TileWindow {
    Tile core, window;
};

/// The image cut into cores of `side` × `side` pixels (tile_grid()), each read with `margin`
/// more pixels on every side where the image has them. Error unless side ≥ 1, margin ≥ 0.
std::vector<TileWindow> tile_windows(long field_nx, long field_ny, long side, long margin);

/// The grid of tile_grid() as lines "IX IY X0 Y0 X1 Y1" (IX, IY from 0: the tile's column and
/// row; the rest its --tile arguments), flushed; Error naming `name` when `out` fails.
void write_tile_grid(std::ostream& out, const std::string& name, long field_nx, long field_ny,
                     long width, long height);

}  // namespace shapesim
