#include "smooth/source_fields.hpp"

#include "app/options.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace shapesim::app {

namespace {

// --field IMAGE=ARCMIN2[@MAG]'s area and magnitude (after the '=' at `eq`); `completeness_given`
// says whether @MAG was there.
SourceField parse_counted_field(const std::string& text, std::size_t eq, bool& completeness_given) {
    SourceField f;
    f.image = text.substr(0, eq);
    const std::string rest = text.substr(eq + 1);
    const std::size_t at = rest.find('@');
    try {
        std::size_t used = 0;
        f.area_arcmin2 = std::stod(rest.substr(0, at), &used);
        if (used != rest.substr(0, at).size()) throw std::invalid_argument("trailing");
        if (at != std::string::npos) {
            f.completeness = std::stod(rest.substr(at + 1), &used);
            if (used != rest.size() - at - 1) throw std::invalid_argument("trailing");
        }
    } catch (const std::exception&) {
        throw po::error("--field wants IMAGE=ARCMIN2[@MAG] or IMAGE=shapes, got '" + text + "'");
    }
    if (!(f.area_arcmin2 > 0.0) || !(std::isfinite(f.area_arcmin2)) ||
        (at != std::string::npos && !std::isfinite(f.completeness)))
        throw po::error("--field " + text + ": the area must be > 0, the magnitude finite");
    completeness_given = at != std::string::npos;
    return f;
}

}  // namespace

std::vector<std::string> SourceFields::images() const {
    std::vector<std::string> images;
    for (const SourceField& f : counted) images.push_back(f.image);
    images.insert(images.end(), shape_images.begin(), shape_images.end());
    return images;
}

void SourceFields::complete() {
    for (SourceField& f : counted) std::sort(f.mags.begin(), f.mags.end());
    for (std::size_t k = 0; k < completeness_given.size(); ++k)
        if (!completeness_given[k]) counted[k].completeness = count_turnover(counted[k].mags);
}

SourceFields read_source_fields(const std::string& like, std::optional<double> area,
                                std::optional<double> pixel_scale,
                                const std::vector<std::string>& specs) {
    SourceFields out;
    if (int(!like.empty()) + int(area.has_value()) + int(!specs.empty()) > 1)
        throw po::error("give one of --like, --area and --field");
    if (!like.empty())
        out.counted.push_back(
            SourceField{"", read_field_geometry(like, pixel_scale).area_arcmin2(), {}});
    else if (area)
        out.counted.push_back(SourceField{"", *area, {}});
    const auto known = [&](const std::string& image) {
        return std::find(out.shape_images.begin(), out.shape_images.end(), image) !=
                   out.shape_images.end() ||
               std::any_of(out.counted.begin(), out.counted.end(),
                           [&](const SourceField& g) { return g.image == image; });
    };
    for (const std::string& text : specs) {
        const std::size_t eq = text.rfind('=');
        if (eq == std::string::npos || eq == 0)
            throw po::error("--field wants IMAGE=ARCMIN2[@MAG] or IMAGE=shapes, got '" + text +
                            "'");
        if (text.substr(eq + 1) == "shapes") {
            if (known(text.substr(0, eq)))
                throw po::error("--field " + text.substr(0, eq) + " given twice");
            out.shape_images.push_back(text.substr(0, eq));
            continue;
        }
        bool completeness_given = false;
        SourceField f = parse_counted_field(text, eq, completeness_given);
        if (known(f.image)) throw po::error("--field " + f.image + " given twice");
        out.completeness_given.push_back(completeness_given);
        out.counted.push_back(std::move(f));
    }
    if (!specs.empty() && out.counted.empty())
        throw po::error(
            "--field: at least one field must give its area (only shape-only fields given)");
    return out;
}

void add_field_stars(SourceFields& fields, const std::vector<std::string>& specs) {
    for (const std::string& spec : specs) {
        if (fields.counted.empty())
            throw po::error("--stars needs the field they were counted in: --like, --area or "
                            "--field IMAGE=ARCMIN2");
        const std::size_t eq = spec.find('=');
        SourceField* field = nullptr;
        std::string file = spec;
        if (eq == std::string::npos) {
            if (fields.counted.size() > 1)
                throw po::error("--stars " + spec + ": several fields; give --stars IMAGE=FILE");
            field = &fields.counted.front();
        } else {
            const std::string image = spec.substr(0, eq);
            file = spec.substr(eq + 1);
            for (SourceField& f : fields.counted)
                if (f.image == image) field = &f;
            if (!field)
                throw po::error("--stars " + spec + ": '" + image +
                                "' is none of the counted --field images");
        }
        if (field->star_mags)
            throw po::error("--stars " + spec + ": that field's stars were given already");
        std::vector<double> mags;
        JsonlReader reader(file, {SourceRecord::schema});
        SourceRecord star;
        while (reader.next_record(star))
            if (star.mag) mags.push_back(*star.mag);
        std::sort(mags.begin(), mags.end());
        field->star_mags = std::move(mags);
    }
}

}  // namespace shapesim::app
