// Detection as shapesim-detect runs it, for every program that detects (shapesim-detect,
// shapesim-measure): the same options, the same defaults, the same steps — read the image,
// its WCS, zero point and noise map; build the point-source locus; detect_sources().
#pragma once

#include "app/log.hpp"
#include "app/options.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/sources.hpp"
#include "shapesim/stamps.hpp"
#include "shapesim/stellarity.hpp"

#include <functional>
#include <string>
#include <vector>

namespace shapesim::app {

/// The detected field and what its records need. A tile's run is the tile's window as an
/// image of its own: positions in it are the window's (shift_to_image() moves them back).
struct DetectionRun {
    SourceContext context;   ///< geometry, zero point, noise correlation (stamps left empty)
    PointSourceLocus locus;  ///< the PSF's point-source locus for the stellarity
    /// Where the locus came from, for the run's summary line: the PSF file, or the assumed
    /// Gaussian (an assumption a user should see: it can call a star a galaxy).
    std::string locus_note;
    DetectionResult field;   ///< detections, segmentation, background-subtracted image
};

/// How a run cut its image: the tiles, and the objects that lie in one tile's core but reach
/// the edge of its window (cut by the tile: flagged "tile_truncated").
struct TiledRun {
    std::vector<TileWindow> tiles;  ///< one, the whole image, when not tiled
    long truncated = 0;             ///< objects cut by their window's edge inside the image
    bool tiled() const { return tiles.size() > 1; }
};

/// What a program does with one tile's run: `owned` are the indices (into run.field.objects)
/// of the objects in the tile's core, each owned by exactly one tile.
using TileSink = std::function<void(DetectionRun& run, const TileWindow& tile,
                                    const std::vector<std::size_t>& owned)>;

/// A record found in a tile's window, moved to the image's pixels: x, y and the extra fields
/// x_peak, y_peak, x_asym, y_asym (where present) shifted by the window's origin; the id made
/// unique across tiles by `id_offset` (added to its number). RA and Dec are already the
/// image's (the window's WCS is the image's, moved).
void shift_to_image(Json& record, const TileWindow& tile, long id_offset);

struct DetectionSettings {
    std::string image, weight, weight_type = "weight", filter = "default", filter_mode = "conv";
    std::string psf_image, psf_model, psf_analytic;
    double pixel_scale = 0.0, ra = 0.0, dec = 0.0, zero_point = 0.0;
    double psf_fwhm = 0.15, psf_pixel_scale = 0.0, star_threshold = 0.97;
    double saturation = 0.0;  ///< --saturation (0: none; not given: the header's SATURATE)
    std::vector<double> psf_box;
    /// --tile-side: "auto" (tiles of 2048² when the image has more than 4096² pixels), "none",
    /// or the tiles' side in pixels; --tile-margin: pixels read beyond each tile's core.
    std::string tile_side = "auto";
    long tile_margin = 256;
    bool no_clean = false, no_rescale = false;
    DetectionOptions detection;

    /// The positional IMAGE (required unless `image_required` is false) and the groups
    /// "Input", "Detection (SExtractor parameters)" and "Stars".
    void declare(ProgramOptions& options, bool image_required = true);
    /// Check the values and run the detection on the whole image (Error / po::error on bad
    /// input).
    DetectionRun run(const ProgramOptions& options, const Log& log);
    /// Check the values and run the detection tile by tile (--tile-side), handing each tile's run
    /// to `sink` in turn, so that memory is bounded by the tile, not the image. Each tile is
    /// detected as an image of its own (its own background mesh, aligned with the image's, and
    /// noise statistics); an object belongs to the tile whose core holds its centroid.
    TiledRun run_tiles(const ProgramOptions& options, const Log& log, const TileSink& sink);
};

/// The stamps' options (--stamp-factor, --stamp-offset, --stamp-sky-margin, --stamp-max-side,
/// --border-width), added in that order to the group `add` adds to.
void declare_stamp_options(po::options_description_easy_init& add, StampOptions& stamp);
/// The sky noise measurement's options (--noise-radius, --noise-grow, --noise-mask-snr).
void declare_sky_noise_options(po::options_description_easy_init& add, SkyNoiseOptions& noise);

}  // namespace shapesim::app
