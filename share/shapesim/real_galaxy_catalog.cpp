#include "shapesim/real_galaxy_catalog.hpp"

#include "shapesim/error.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/stamps.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <utility>

namespace shapesim {

namespace {

// `path` without cfitsio's `[...]` part, and its folder ("." when it has none).
std::string folder_of(const std::string& path) {
    std::string file = path.substr(0, path.find('['));
    const auto slash = file.rfind('/');
    return slash == std::string::npos ? "." : file.substr(0, slash == 0 ? 1 : slash);
}

// Move to the first table HDU unless `path` named one.
void move_to_table(FitsReader& fits, const std::string& path) {
    if (path.find('[') != std::string::npos) return;
    for (const FitsHduInfo& hdu : fits.list_hdus())
        if (!hdu.is_image) {
            fits.move_to(hdu.index);
            return;
        }
    throw Error("no table in the file (a RealGalaxyCatalog is a FITS binary table)", path);
}

// An integer-valued cell (an HDU number) as an int; Error at the row otherwise.
int hdu_number(double value, const std::string& place, long row, const std::string& column) {
    if (!(value >= 0.0 && value < 1e6 && value == std::floor(value)))
        throw Error("must be a whole number ≥ 0, got " + std::to_string(value), place, row,
                    column);
    return int(value);
}

// IDENT as text: an integer column's value as its digits.
std::vector<std::string> identifiers(FitsReader& fits) {
    if (fits.column_is_text("IDENT")) return fits.read_text_column("IDENT");
    std::vector<std::string> out;
    for (const double v : fits.read_column("IDENT")) {
        char text[64];
        if (v == std::floor(v) && std::fabs(v) < 9e15)
            std::snprintf(text, sizeof text, "%.0f", v);
        else
            std::snprintf(text, sizeof text, "%.17g", v);
        out.emplace_back(text);
    }
    return out;
}

}  // namespace

std::vector<RealGalaxy> read_real_galaxy_catalog(const std::string& path,
                                                 const std::string& image_folder) {
    FitsReader fits(path);
    move_to_table(fits, path);
    const std::string place = fits.place();
    const long rows = fits.table_rows();
    const std::string folder = image_folder.empty() ? folder_of(path) : image_folder;

    const std::vector<std::string> ident = identifiers(fits);
    const std::vector<double> mag = fits.read_column("MAG");
    const std::vector<std::string> gal_file = fits.read_text_column("GAL_FILENAME");
    const std::vector<double> gal_hdu = fits.read_column("GAL_HDU");
    const std::vector<std::string> psf_file = fits.read_text_column("PSF_FILENAME");
    const std::vector<double> psf_hdu = fits.read_column("PSF_HDU");
    const std::vector<double> scale = fits.read_column("PIXEL_SCALE");
    const std::vector<double> variance = fits.read_column("NOISE_VARIANCE");
    const auto optional_column = [&](const char* name) {
        return fits.has_column(name) ? fits.read_column(name) : std::vector<double>{};
    };
    const std::vector<double> weight = optional_column("WEIGHT");
    const std::vector<double> noise_mean = optional_column("NOISE_MEAN");
    const std::vector<double> ra = optional_column("RA");
    const std::vector<double> dec = optional_column("DEC");
    const std::vector<std::string> band =
        fits.has_column("BAND") ? fits.read_text_column("BAND") : std::vector<std::string>{};

    std::vector<RealGalaxy> galaxies;
    galaxies.reserve(std::size_t(rows));
    for (long r = 0; r < rows; ++r) {
        const std::size_t i = std::size_t(r);
        const long row = r + 1;
        const auto positive = [&](double v, const char* column) {
            if (!(std::isfinite(v) && v > 0.0))
                throw Error("must be > 0, got " + std::to_string(v), place, row, column);
            return v;
        };
        const auto file_name = [&](const std::string& name, const char* column) {
            if (name.empty()) throw Error("empty file name", place, row, column);
            return name.front() == '/' ? name : folder + "/" + name;
        };
        RealGalaxy g;
        g.row = row;
        g.ident = ident[i];
        if (g.ident.empty()) throw Error("empty identifier", place, row, "IDENT");
        g.mag = mag[i];
        if (!std::isfinite(g.mag)) throw Error("not a finite magnitude", place, row, "MAG");
        g.image = file_name(gal_file[i], "GAL_FILENAME") + "[" +
                  std::to_string(hdu_number(gal_hdu[i], place, row, "GAL_HDU")) + "]";
        g.psf = file_name(psf_file[i], "PSF_FILENAME") + "[" +
                std::to_string(hdu_number(psf_hdu[i], place, row, "PSF_HDU")) + "]";
        g.pixel_scale = positive(scale[i], "PIXEL_SCALE");
        g.noise_variance = positive(variance[i], "NOISE_VARIANCE");
        if (!weight.empty()) {
            g.weight = weight[i];
            if (!(std::isfinite(g.weight) && g.weight >= 0.0))
                throw Error("must be ≥ 0, got " + std::to_string(g.weight), place, row, "WEIGHT");
        }
        if (!noise_mean.empty()) {
            g.noise_mean = noise_mean[i];
            if (!std::isfinite(g.noise_mean))
                throw Error("not a finite number", place, row, "NOISE_MEAN");
        }
        if (!ra.empty() && !dec.empty() && std::isfinite(ra[i]) && std::isfinite(dec[i])) {
            g.ra = ra[i];
            g.dec = dec[i];
        }
        if (!band.empty()) g.band = band[i];
        galaxies.push_back(std::move(g));
    }
    return galaxies;
}

std::vector<std::size_t> absent_psf_files(const std::vector<RealGalaxy>& galaxies) {
    std::map<std::string, bool> present;  // a catalogue names a few PSF files many times
    std::vector<std::size_t> absent;
    for (std::size_t i = 0; i < galaxies.size(); ++i) {
        const std::string file = galaxies[i].psf.substr(0, galaxies[i].psf.find('['));
        auto [at, fresh] = present.try_emplace(file, false);
        if (fresh) at->second = std::ifstream(file).good();
        if (!at->second) absent.push_back(i);
    }
    return absent;
}

PsfImage read_real_galaxy_psf(const RealGalaxy& galaxy, const std::string& catalogue) {
    try {
        return read_psf_image(galaxy.psf, galaxy.pixel_scale);
    } catch (const Error& e) {
        throw Error(e.where_what(), catalogue, galaxy.row, "PSF_FILENAME");
    }
}

PsfModel real_galaxy_psf(const PsfImage& image, double pixel_scale, int stamp_pixels,
                         const PsfFitOptions& options) {
    PsfModel psf = psf_from_oversampled(image.pixels, image.pixel_scale, pixel_scale, {},
                                        stamp_pixels, options);
    psf.model.x = psf.model.y = 0.0;
    return psf;
}

DecomposeJob real_galaxy_job(const RealGalaxy& galaxy, const std::string& catalogue,
                             double gain) {
    DecomposeJob job;
    job.line = galaxy.row;
    job.pixel_scale = galaxy.pixel_scale;
    Stamp& stamp = job.stamp;
    stamp.id = galaxy.ident;
    try {
        FitsReader fits(galaxy.image);
        stamp.image = fits.read_image() - galaxy.noise_mean;
    } catch (const Error& e) {
        throw Error(e.where_what(), catalogue, galaxy.row, "GAL_FILENAME");
    }
    stamp.weight = ImageArray::Constant(stamp.image.rows(), stamp.image.cols(),
                                        1.0 / galaxy.noise_variance);
    stamp.mask = ImageArray::Zero(stamp.image.rows(), stamp.image.cols());
    // Bad pixels (NaN, ±Inf) weigh nothing and hold nothing.
    long good = 0;
    for (Eigen::Index k = 0; k < stamp.image.size(); ++k) {
        if (std::isfinite(stamp.image(k))) {
            ++good;
        } else {
            stamp.image(k) = 0.0;
            stamp.weight(k) = 0.0;
        }
    }
    if (good == 0)
        throw Error(galaxy.image + ": no finite pixel in the stamp", catalogue, galaxy.row,
                    "GAL_FILENAME");

    // Catalogue stamps are meant to be cleaned of neighbours, but not all are (GalSim's AEGIS
    // examples hold up to eleven): the stamp is detected as an image (one background tile,
    // the catalogue's variance as the noise), the segment at the stamp's centre (else the
    // nearest detection) is the galaxy, and the other segments are masked as cut_stamp()
    // masks a field's neighbours. The detection starts the fit's search.
    DetectionOptions detection;
    detection.back_size = int(std::max(stamp.image.rows(), stamp.image.cols()));
    detection.rescale_weight = false;
    const DetectionResult found = detect_sources(stamp.image, &stamp.weight, detection);
    SourceRecord& source = job.source;
    source.id = galaxy.ident;
    source.x = 0.5 * double(stamp.image.cols() + 1);
    source.y = 0.5 * double(stamp.image.rows() + 1);
    const Detection* galaxy_found = nullptr;
    const int centre_label = found.segmentation(Eigen::Index(stamp.image.rows() / 2),
                                                Eigen::Index(stamp.image.cols() / 2));
    for (const Detection& d : found.objects) {
        const auto distance = [&](const Detection& o) {
            return std::hypot(o.x - source.x, o.y - source.y);
        };
        if (d.label == centre_label ||
            (centre_label == 0 && (!galaxy_found || distance(d) < distance(*galaxy_found))))
            galaxy_found = &d;
    }
    if (galaxy_found) {
        source.x = galaxy_found->x;
        source.y = galaxy_found->y;
        source.a = galaxy_found->a;
        source.b = galaxy_found->b;
        source.theta = galaxy_found->theta;
        source.flux = galaxy_found->flux_auto;
        for (Eigen::Index y = 0; y < stamp.image.rows(); ++y)
            for (Eigen::Index x = 0; x < stamp.image.cols(); ++x)
                if (const int label = found.segmentation(y, x);
                    label != 0 && label != galaxy_found->label)
                    stamp.mask(y, x) = 1.0;
    }
    job.noise_correlation = std::max(1.0, found.noise_correlation);
    if (gain > 0.0) add_source_noise(stamp, gain);
    source.extra["noise_correlation"] = job.noise_correlation;
    source.extra["neighbours_masked"] =
        galaxy_found ? long(found.objects.size()) - 1 : long(found.objects.size());
    source.mag = galaxy.mag;
    source.ra = galaxy.ra;
    source.dec = galaxy.dec;
    source.extra["image"] = catalogue;
    source.extra["pixel_scale"] = galaxy.pixel_scale;
    source.extra["weight"] = galaxy.weight;
    source.extra["catalogue_row"] = galaxy.row;
    source.extra["stamp"] = galaxy.image;
    source.extra["psf_image"] = galaxy.psf;
    source.extra["noise_variance"] = galaxy.noise_variance;
    if (!galaxy.band.empty()) source.extra["band"] = galaxy.band;
    return job;
}

}  // namespace shapesim
