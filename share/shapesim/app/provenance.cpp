#include "shapesim/app/provenance.hpp"

#include <algorithm>
#include <string>

namespace shapesim::app {

std::vector<FitsKeyword> provenance_keywords(const ProgramOptions& options,
                                             const std::vector<std::string>& outputs) {
    std::vector<FitsKeyword> keywords;
    for (const auto& [name, value] : options.settings()) {
        const bool output = std::find(outputs.begin(), outputs.end(), name) != outputs.end();
        if (!output && name != "threads" && name != "quiet" && name != "verbose")
            keywords.emplace_back("OPTION " + name, value);
    }
    return keywords;
}

}  // namespace shapesim::app
