#include "app/gnuplot.hpp"

#include "shapesim/error.hpp"

#include <cstdlib>

namespace shapesim::app {

bool run_gnuplot(const std::string& script, const std::string& log_path) {
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) return false;
    const std::string command = "gnuplot '" + script + "' 2>'" + log_path + "'";
    if (std::system(command.c_str()) != 0)
        throw Error("gnuplot failed on the figures (see " + log_path + ")", script);
    return true;
}

}  // namespace shapesim::app
