#include "shapesim/colours.hpp"

#include "shapesim/error.hpp"

#include <cmath>
#include <iomanip>
#include <map>
#include <ostream>
#include <sstream>

namespace shapesim {

ColourCatalogue ColourCatalogue::from_records(std::string name,
                                              const std::vector<SourceRecord>& records) {
    ColourCatalogue c;
    c.name = std::move(name);
    for (const SourceRecord& r : records) {
        if (!r.extra.contains("bands"))
            throw Error("record " + r.id + " has no bands (shapesim-detect --bands)", "", 0,
                        "bands");
        const Json& list = required_array(r.extra, "bands");
        std::vector<std::string> names;
        Galaxy g;
        for (const Json& e : list) {
            names.push_back(required_string(e, "band"));
            g.flux.push_back(required_double(e, "flux"));
            g.error.push_back(required_double(e, "flux_err"));
            g.inner.push_back(optional_double(e, "flux_inner").value_or(NAN));
        }
        if (c.bands.empty()) c.bands = names;
        if (names != c.bands)
            throw Error("record " + r.id + "'s bands differ from the first record's", "", 0,
                        "bands");
        const bool star = r.extra.contains("kind") && r.extra.at("kind") == "star";
        if (star || !r.mag) continue;
        g.mag = *r.mag;
        c.galaxies.push_back(std::move(g));
    }
    if (c.bands.size() < 2) throw Error("a colour needs at least two bands", c.name);
    return c;
}

std::vector<double> ColourCatalogue::colours(std::size_t b, double mag_limit,
                                             std::vector<double>* mags) const {
    std::vector<double> out;
    for (const Galaxy& g : galaxies) {
        if (!(g.mag <= mag_limit) || !(g.flux[b] > 0.0) || !(g.flux[b + 1] > 0.0)) continue;
        out.push_back(-2.5 * std::log10(g.flux[b] / g.flux[b + 1]));
        if (mags) mags->push_back(g.mag);
    }
    return out;
}

std::vector<double> ColourCatalogue::gradients(std::size_t b, double mag_limit) const {
    std::vector<double> out;
    for (const Galaxy& g : galaxies) {
        if (!(g.mag <= mag_limit)) continue;
        const double in0 = g.inner[b], in1 = g.inner[b + 1];
        const double out0 = g.flux[b] - in0, out1 = g.flux[b + 1] - in1;
        if (!(in0 > 0.0 && in1 > 0.0 && out0 > 0.0 && out1 > 0.0)) continue;
        out.push_back(-2.5 * std::log10(in0 / in1) + 2.5 * std::log10(out0 / out1));
    }
    return out;
}

std::vector<std::vector<ColourComparison>> compare_colours(
    const std::vector<ColourCatalogue>& catalogues, double mag_limit, int resamples,
    std::uint64_t seed) {
    require(!catalogues.empty(), "no catalogue to compare");
    for (const ColourCatalogue& c : catalogues)
        if (c.bands != catalogues.front().bands)
            throw Error("its bands differ from " + catalogues.front().name + "'s", c.name);
    const ColourCatalogue& reference = catalogues.front();
    std::vector<std::vector<ColourComparison>> out;
    for (const ColourCatalogue& c : catalogues) {
        std::vector<ColourComparison> row;
        for (std::size_t b = 0; b + 1 < c.bands.size(); ++b) {
            ColourComparison k;
            k.colour = c.bands[b] + "-" + c.bands[b + 1];
            const std::vector<double> colours = c.colours(b, mag_limit);
            const std::vector<double> gradients = c.gradients(b, mag_limit);
            const std::vector<double> ref_colours = reference.colours(b, mag_limit);
            const std::vector<double> ref_gradients = reference.gradients(b, mag_limit);
            k.n = colours.size();
            k.n_gradient = gradients.size();
            if (!colours.empty()) {
                k.mean = mean_of(colours);
                k.mean_error = bootstrap_error(colours, mean_of, resamples, seed + b);
            }
            if (!gradients.empty()) k.gradient_median = median_of_values(gradients);
            if (!colours.empty() && !ref_colours.empty()) {
                k.colour_ks = ks_two_sample(colours, ref_colours);
                const double ref_error = bootstrap_error(ref_colours, mean_of, resamples, seed + b);
                const double both = std::hypot(k.mean_error, ref_error);
                k.mean_offset_sigmas = both > 0.0 ? (k.mean - mean_of(ref_colours)) / both : 0.0;
            }
            if (!gradients.empty() && !ref_gradients.empty())
                k.gradient_ks = ks_two_sample(gradients, ref_gradients);
            row.push_back(k);
        }
        out.push_back(std::move(row));
    }
    return out;
}

void write_colour_report(std::ostream& out, const std::vector<ColourCatalogue>& catalogues,
                         const std::vector<std::vector<ColourComparison>>& comparisons,
                         double mag_limit) {
    const auto fixed = [&](double v, int digits) {
        std::ostringstream s;
        s << std::fixed << std::setprecision(digits) << v;
        return s.str();
    };
    out << "Colours of galaxies with detection-band mag <= " << fixed(mag_limit, 2)
        << " (both AUTO fluxes > 0), each catalogue against " << catalogues.front().name
        << ": mean with its bootstrap error, the offset of the means in their errors, KS of the "
           "colours and of the gradients (inner - outer colour).\n\n"
        << "| colour | catalogue | n | mean | offset (sigma) | KS D | KS p | n grad | "
           "median grad | grad KS D | grad KS p |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (std::size_t b = 0; b < comparisons.front().size(); ++b)
        for (std::size_t c = 0; c < catalogues.size(); ++c) {
            const ColourComparison& k = comparisons[c][b];
            out << "| " << k.colour << " | " << catalogues[c].name << " | " << k.n << " | "
                << fixed(k.mean, 3) << " ± " << fixed(k.mean_error, 3) << " | "
                << fixed(k.mean_offset_sigmas, 2) << " | " << fixed(k.colour_ks.d, 3) << " | "
                << fixed(k.colour_ks.p_value, 3) << " | " << k.n_gradient << " | "
                << fixed(k.gradient_median, 3) << " | " << fixed(k.gradient_ks.d, 3) << " | "
                << fixed(k.gradient_ks.p_value, 3) << " |\n";
        }
    // The colour–magnitude relation: the median colour per 1-mag bin of the detection band.
    out << "\nColour-magnitude: median colour per 1-mag bin (n in brackets).\n\n| colour | bin |";
    for (const ColourCatalogue& c : catalogues) out << " " << c.name << " |";
    out << "\n|---|---|";
    for (std::size_t c = 0; c < catalogues.size(); ++c) out << "---|";
    out << "\n";
    for (std::size_t b = 0; b + 1 < catalogues.front().bands.size(); ++b) {
        std::vector<std::map<int, std::vector<double>>> bins(catalogues.size());
        int lo = 1000, hi = -1000;
        for (std::size_t c = 0; c < catalogues.size(); ++c) {
            std::vector<double> mags;
            const std::vector<double> colours = catalogues[c].colours(b, mag_limit, &mags);
            for (std::size_t i = 0; i < colours.size(); ++i) {
                const int bin = int(std::floor(mags[i]));
                bins[c][bin].push_back(colours[i]);
                lo = std::min(lo, bin);
                hi = std::max(hi, bin);
            }
        }
        for (int bin = lo; bin <= hi; ++bin) {
            out << "| " << comparisons.front()[b].colour << " | " << bin << "-" << bin + 1 << " |";
            for (std::size_t c = 0; c < catalogues.size(); ++c) {
                const auto it = bins[c].find(bin);
                if (it == bins[c].end()) out << " - |";
                else
                    out << " " << fixed(median_of_values(it->second), 2) << " ("
                        << it->second.size() << ") |";
            }
            out << "\n";
        }
    }
}

}  // namespace shapesim
