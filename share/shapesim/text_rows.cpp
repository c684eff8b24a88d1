#include "shapesim/text_rows.hpp"

#include "shapesim/error.hpp"

#include <istream>

namespace shapesim {

void for_each_text_row(std::istream& in, const std::string& name,
                       const std::function<void(const std::string& text, long line)>& row) {
    std::string text;
    long line = 0, rows = 0;
    while (std::getline(in, text)) {
        ++line;
        if (const auto hash = text.find('#'); hash != std::string::npos) text.erase(hash);
        if (text.find_first_not_of(" \t\r\v\f") == std::string::npos) continue;
        if (++rows > max_text_rows) throw Error("more than 10^6 rows", name, line);
        row(text, line);
    }
    if (in.bad()) throw Error("read failed", name);
}

}  // namespace shapesim
