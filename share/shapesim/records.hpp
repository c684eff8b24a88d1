// Catalogue records: one struct per JSON-lines schema (DESIGN §2), each read and written through
// its table of fields (record_fields.hpp). `from_json` reads with errors naming the field and
// keeps unknown fields in `extra`, written back by `to_json`. The schemas, their units and the
// multi-band `bands`: docs/library.md, "Records".
#pragma once

#include "shapesim/jsonl.hpp"
#include "shapesim/model.hpp"
#include "shapesim/transform.hpp"

#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// Largest n_max a record may declare: a stated bound on one record's cost. Rendering one
/// model grows as n_max⁴ (n_max 100: 0.13 s, 200: 1.8 s and 80 MB; 1000 ran past 120 s and
/// 2.2 GB); decompose fits to n_max 100 at most, the stress tests go to 101.
constexpr int record_n_max_limit = 200;

/// One band of a multi-band field (`shapesim.band/1`): a line of the bands file that
/// shapesim-detect --bands and shapesim-decompose read. The images are on the detection
/// image's pixel grid.
struct BandRecord {
    static constexpr const char* schema = "shapesim.band/1";
    std::string band;                    ///< its name (e.g. "f814w"), unique in the file
    std::string image;                   ///< science image (path)
    std::string weight;                  ///< noise map (path; empty: none)
    std::string weight_type = "weight";  ///< "weight", "rms" or "variance"
    std::optional<double> zero_point;    ///< AB magnitude of one image unit
    std::optional<double> gain;          ///< e⁻ per image unit (source photon noise)
    std::string psf;                     ///< the band's PSF record (path; empty: none; kept
                                         ///< for the user: decompose takes --band-psf)
    Json extra = Json::object();

    static BandRecord from_json(const Json& record);
    Json to_json() const;
    void validate() const;
    /// Every record of the bands file `path`; Error (file and line) on a bad or repeated band,
    /// or an empty file.
    static std::vector<BandRecord> read_all(const std::string& path);
};

/// One band of a multi-band model: its coefficients at the record's centre, β and n_max.
struct BandCoefficients {
    std::string band;
    std::vector<Complex> coeffs;     ///< packed a_{n,m}, size polar_count(n_max); a star's none
    std::optional<double> flux, flux_err, mag, chi2r;
    Json extra = Json::object();     ///< e.g. coeff_errors, zero_point

    /// Read element `field` (for messages, e.g. "bands[2]") of a record of order `n_max`.
    static BandCoefficients from_json(const Json& j, int n_max, const std::string& field);
    Json to_json() const;
};

/// A detection (`shapesim.source/1`, from shapesim-detect).
struct SourceRecord {
    static constexpr const char* schema = "shapesim.source/1";
    std::string id;                    ///< string (an integer id on input is accepted)
    double x = 0.0, y = 0.0;           ///< centroid, FITS pixels
    std::optional<double> ra, dec;     ///< degrees, when the image has a WCS
    double flux = 0.0;                 ///< image units
    std::optional<double> flux_err;    ///< image units, ≥ 0
    std::optional<double> mag;         ///< absent when flux ≤ 0 or no zero point
    std::optional<double> a, b;        ///< semi-axes, pixels, ≥ 0
    std::optional<double> theta;       ///< degrees CCW from +x
    std::optional<double> fwhm;        ///< pixels, ≥ 0
    std::optional<double> stellarity;  ///< 0 (galaxy) … 1 (star)
    std::vector<std::string> flags;
    Json extra = Json::object();  ///< unknown fields, carried through

    static SourceRecord from_json(const Json& record);
    Json to_json() const;
    /// Throws Error (field set) unless every value is in range.
    void validate() const;
};

/// A shapelet model (`shapesim.shapelet/1`, from shapesim-decompose; also the PSF).
struct ShapeletRecord {
    static constexpr const char* schema = "shapesim.shapelet/1";
    std::string id;
    double x = 0.0, y = 0.0;   ///< model centre, FITS pixels
    double beta = 0.0;         ///< arcsec, > 0
    double pixel_scale = 0.0;  ///< arcsec per pixel, > 0
    int n_max = 0;
    std::vector<Complex> coeffs;  ///< packed a_{n,m}, size polar_count(n_max)
    std::optional<double> chi2r;  ///< reduced χ² of the fit
    std::optional<double> flux;   ///< 2√π β_pix Σ_{n even} a_{n,0}, image units
    std::optional<double> mag;
    std::vector<std::string> flags;
    Json extra = Json::object();
    std::vector<BandCoefficients> bands;  ///< multi-band: every band (the reference's too)

    static ShapeletRecord from_json(const Json& record);
    Json to_json() const;
    /// Throws Error unless beta, pixel_scale > 0, the coefficient count fits n_max, every
    /// a_{n,0} is real and all values are finite.
    void validate() const;

    /// The model in pixel units: beta_pix = beta / pixel_scale (exactly that double).
    ShapeletModel to_model() const;
    /// A record of `model` at `pixel_scale` (beta = beta_pix · pixel_scale); flux is
    /// recomputed from the coefficients; chi2r, mag, flags left for the caller.
    static ShapeletRecord from_model(const ShapeletModel& model, double pixel_scale,
                                     std::string id);
};

/// A simulated object (`shapesim.object/1`, from shapesim-sample).
struct ObjectRecord {
    static constexpr const char* schema = "shapesim.object/1";
    std::string id;
    std::string kind = "galaxy";  ///< "galaxy" or "star"
    double ra = 0.0, dec = 0.0;   ///< degrees
    std::optional<double> x, y;   ///< FITS pixels in the `--like` field, when known
    std::optional<double> mag;
    double flux = 0.0;  ///< image units
    // The shape: required for galaxies; a star is drawn as the PSF and may omit it.
    double beta = 0.0;         ///< arcsec
    double pixel_scale = 0.0;  ///< arcsec per pixel of the coefficients' units
    int n_max = 0;
    std::vector<Complex> coeffs;        ///< packed a_{n,m}; empty = no shape
    std::optional<std::string> parent;  ///< id of the real galaxy it was drawn from
    std::vector<std::string> flags;
    /// The lensing this galaxy sees (shapesim-lens): "lensing": {"g1", "g2", "kappa",
    /// "magnify"}; render applies it before the PSF. |g| < 1, κ < 1; magnify false keeps the flux.
    std::optional<Lensing> lensing;
    Json extra = Json::object();
    std::vector<BandCoefficients> bands;  ///< multi-band: every band (fluxes in its units)

    static ObjectRecord from_json(const Json& record);
    /// The same, with "coeffs" already read as number pairs when coeffs.found (JsonlReader's
    /// fast path: the coefficients are most of a line); its values are moved out.
    static ObjectRecord from_json(const Json& record, NumberPairs& coeffs);
    static constexpr const char* pairs_key = "coeffs";
    Json to_json() const;
    void validate() const;
    /// True when the record carries a shapelet shape.
    bool has_shape() const { return !coeffs.empty(); }
    /// The shape as a model centred at (`x`, `y`) (FITS pixels), beta_pix = beta/pixel_scale.
    ShapeletModel to_model(double x, double y) const;
    /// This record as seen in band `name`: coefficients, flux and mag of that band (stars and
    /// galaxies alike); `bands` emptied. Error when the record has no such band.
    ObjectRecord in_band(const std::string& name) const;
};

/// What shapesim-render drew of one object (`shapesim.truth/1`, its --truth): the position, the
/// light drawn and, for a galaxy, its shape after lensing and before the PSF.
struct TruthRecord {
    static constexpr const char* schema = "shapesim.truth/1";
    std::string id;
    std::string kind = "galaxy";   ///< "galaxy" or "star", as the object record says
    double ra = 0.0, dec = 0.0;    ///< degrees, the object record's
    double x = 0.0, y = 0.0;       ///< model centre, field FITS pixels
    double flux = 0.0;             ///< the light drawn, image units (clipped light included)
    std::optional<double> mag;     ///< the record's mag moved by the flux drawn
    std::optional<double> clipped_flux;  ///< negative light set to zero (written when > 0)
    /// A galaxy's lensed shape before the PSF (moments.hpp; absent for stars). e1, e2 and
    /// rms_radius are undefined (null) when the model's second moments are not positive.
    struct Shape {
        std::optional<double> e1, e2, rms_radius;
        double lensing_error = 0.0;  ///< relative truncation of the lensed projection
        std::optional<double> e1_intrinsic, e2_intrinsic;  ///< before lensing (= e1, e2 unlensed)
        /// The lensing applied: reduced shear, convergence, magnification (0, 0, 0, 1: none).
        double g1 = 0.0, g2 = 0.0, kappa = 0.0, mu = 1.0;
    };
    std::optional<Shape> shape;
    int n_max = 0;                 ///< the drawn (convolved) model's order
    double stamp_radius = 0.0;     ///< R, pixels (scene.hpp stamp_radius())
    Json extra = Json::object();

    static TruthRecord from_json(const Json& record);
    /// Writes what it holds, unvalidated: the truth of what was drawn (JsonlWriter still
    /// refuses a non-finite number, naming the field).
    Json to_json() const;
    void validate() const;
};

/// Morphology of one object (`shapesim.morph/1`, from shapesim-measure). Statistics that
/// could not be measured are absent.
struct MorphRecord {
    static constexpr const char* schema = "shapesim.morph/1";
    std::string id;
    double x = 0.0, y = 0.0;  ///< FITS pixels
    std::optional<double> mag;
    std::optional<double> fwhm, a, b;   ///< pixels
    std::optional<double> theta;        ///< degrees CCW from +x
    std::optional<double> e1, e2;       ///< ellipticity (paper eqs. 6–7)
    std::optional<double> r_petro;      ///< Petrosian radius (η = 0.2), pixels
    std::optional<double> c, a_sym, s;  ///< concentration, asymmetry, clumpiness
    std::optional<double> gini, m20;
    std::vector<std::string> flags;
    Json extra = Json::object();

    static MorphRecord from_json(const Json& record);
    Json to_json() const;
    void validate() const;
};

/// The unit of a catalogue field, by its name (the same name means the same quantity in every
/// schema), as FITS TUNIT and astropy spell it: "deg" (ra, dec, theta, rotation), "pix"
/// (x, y, a, b, fwhm, fwhm_moffat, r_petro, rms_radius, stamp_radius, reach), "arcsec" (beta,
/// psf_beta), "arcsec/pix" (pixel_scale), "mag" (mag, mag_*), `flux_unit` (flux, flux_err,
/// clipped_flux, flux_aper); "" for the dimensionless and the unknown.
std::string field_unit(const std::string& field, const std::string& flux_unit);

/// A line of tests/data/reference/convolved.jsonl: galaxy ⊗ PSF and the exact result.
struct ReferenceConvolutionRecord {
    static constexpr const char* schema = "shapesim.reference_convolution/1";
    std::string galaxy_id;       ///< a model of models.jsonl
    ShapeletRecord psf, result;  ///< full shapelet records
    std::string hdu;             ///< EXTNAME of the image in convolved.fits
    double x = 0.0, y = 0.0;     ///< centre of the convolved image, FITS pixels
    int nx = 0, ny = 0;          ///< stamp size
    double flux = 0.0;           ///< flux_gal × flux_psf
    Json extra = Json::object();

    static ReferenceConvolutionRecord from_json(const Json& record);
    Json to_json() const;
};

/// Whether `flags` holds `flag`.
bool has_flag(const std::vector<std::string>& flags, const std::string& flag);
/// Whether `flags` holds one of the '|'-separated alternatives of `wanted`
/// ("converged|n_max_cap").
bool has_any_flag(const std::vector<std::string>& flags, const std::string& wanted);

}  // namespace shapesim
