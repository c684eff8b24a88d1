#include "app/provenance.hpp"

#include <algorithm>
#include <string>

namespace shapesim::app {

std::vector<FitsKeyword> provenance_keywords(const ProgramOptions& options,
                                             const std::vector<std::string>& outputs) {
    // settings() gives one pair per value: an option of several values (--shear G1 G2,
    // --pixels NX NY) becomes one keyword of them all, space-separated, as it was typed.
    std::vector<std::pair<std::string, std::string>> joined;
    for (const auto& [name, value] : options.settings()) {
        const bool output = std::find(outputs.begin(), outputs.end(), name) != outputs.end();
        if (output || name == "threads" || name == "quiet" || name == "verbose") continue;
        if (!joined.empty() && joined.back().first == name)
            joined.back().second += " " + value;
        else
            joined.emplace_back(name, value);
    }
    std::vector<FitsKeyword> keywords;
    for (const auto& [name, value] : joined) keywords.emplace_back("OPTION " + name, value);
    return keywords;
}

}  // namespace shapesim::app
