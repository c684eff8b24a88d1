// Field geometry: the gnomonic (TAN) world coordinate system and `--like IMAGE`.
//
// Pixel positions are FITS pixel coordinates (first pixel centred at (1, 1)); sky positions
// are (RA, Dec) in degrees; the CD matrix is in degrees per pixel. The projection is the
// FITS "TAN" of Calabretta & Greisen (2002, A&A 395, 1077) with the reference point at the
// native pole (LONPOLE = 180°), in closed form:
//   (ξ, η) = CD · (x − CRPIX1, y − CRPIX2)                      (intermediate, radians)
//   α = α₀ + atan2(ξ, cos δ₀ − η sin δ₀)
//   δ = atan2(η cos δ₀ + sin δ₀, √(ξ² + (cos δ₀ − η sin δ₀)²))
// and its exact inverse, with cos c = sin δ sin δ₀ + cos δ cos δ₀ cos(α − α₀) > 0:
//   ξ = cos δ sin(α − α₀) / cos c,  η = (cos δ₀ sin δ − sin δ₀ cos δ cos(α − α₀)) / cos c.
// Distortion: the SIP convention (Shupe et al. 2005; CTYPE RA---TAN-SIP / DEC--TAN-SIP), the
// one HST, Spitzer and most survey pipelines write: before the CD matrix,
//   u′ = u + Σ A_p_q u^p v^q,  v′ = v + Σ B_p_q u^p v^q   (u, v = x − CRPIX1, y − CRPIX2;
//   2 ≤ p + q ≤ A_ORDER, B_ORDER),
// inverted by Newton's method to 1e−10 pixel (the optional AP/BP inverse polynomials are
// approximations and are not needed). Other projections and distortions (TPV, ZPN, SIN…)
// are refused by name. The pixel scale of a field is √|det CD| in arcsec.
#pragma once

#include <iosfwd>
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

/// A TAN world coordinate system; fields are named after their FITS keywords.
struct Wcs {
    double crpix1 = 0.0, crpix2 = 0.0;  ///< reference pixel (FITS coordinates)
    double crval1 = 0.0, crval2 = 0.0;  ///< reference point (RA, Dec), degrees
    double cd1_1 = 1.0, cd1_2 = 0.0;    ///< CD matrix, degrees per pixel: CDi_j
    double cd2_1 = 0.0, cd2_2 = 1.0;
    std::string ctype1 = "RA---TAN", ctype2 = "DEC--TAN";
    /// RADESYS: the frame RA/Dec are in, as read (ICRS when the header names none; the
    /// formulas do not depend on it). Written back with every WCS.
    std::string radesys = "ICRS";
    /// SIP distortion (CTYPEs end in -SIP): sip_a[p][q] = A_p_q for p + q ≤ sip_order (the
    /// larger of A_ORDER and B_ORDER; missing terms 0); empty without distortion.
    int sip_order = 0;
    std::vector<std::vector<double>> sip_a, sip_b;

    /// True when the WCS carries SIP distortion.
    bool has_sip() const { return sip_order > 0; }
    /// (u′, v′): the SIP-distorted offsets of (u, v) from CRPIX (the identity without SIP).
    std::pair<double, double> distort(double u, double v) const;

    /// Sky position of a pixel position (exact TAN formulas above).
    SkyPosition pixel_to_sky(double x, double y) const;
    /// Pixel position of a sky position; throws Error when it lies 90° or more from CRVAL
    /// (the TAN projection does not reach it).
    PixelPosition sky_to_pixel(double ra, double dec) const;
    /// Pixel scale √|det CD|, arcsec per pixel.
    double pixel_scale_arcsec() const;
    /// The WCS of a cutout whose first pixel is this one's pixel (`x0`, `y0`): CRPIX moved by
    /// (x0 − 1, y0 − 1). SIP terms are in offsets from CRPIX, so they move with it unchanged.
    Wcs cutout(long x0, long y0) const;
    /// Throws Error (field = keyword) unless finite, CTYPE is RA---TAN/DEC--TAN (with -SIP
    /// exactly when it has SIP terms) and det CD ≠ 0.
    void validate() const;
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
