#include "shapesim/text_rows.hpp"

#include "shapesim/error.hpp"

#include <cerrno>
#include <cstring>
#include <istream>

namespace shapesim {

bool read_text_line(std::istream& in, std::string& text, const std::string& name, long line,
                    const char* kind) {
    text.clear();
    char chunk[1 << 16];
    while (true) {
        in.getline(chunk, sizeof chunk);
        const std::streamsize got = in.gcount();
        if (in.bad()) throw Error(std::string("read failed: ") + std::strerror(errno), name);
        if (in.fail() && !in.eof() && got == std::streamsize(sizeof chunk) - 1) {
            // The chunk is full and the line goes on.
            text.append(chunk, std::size_t(got));
            in.clear();
            if (text.size() > max_line_bytes)
                throw Error("a line longer than " + std::to_string(max_line_bytes >> 20) +
                                " MiB: not " + std::string(kind) + " (no newline?)",
                            name, line);
            continue;
        }
        if (in.eof()) {
            // The last line, without a newline; none at all when nothing was read.
            text.append(chunk, std::size_t(got));
            if (got == 0 && text.empty()) return false;
            in.clear(std::ios::eofbit);
            return true;
        }
        if (in.fail()) return false;
        text.append(chunk, std::size_t(got) - 1);  // the newline was extracted and counted
        return true;
    }
}

void for_each_text_row(std::istream& in, const std::string& name,
                       const std::function<void(const std::string& text, long line)>& row) {
    static_assert(max_text_rows == 1000000, "the message below names the bound");
    std::string text;
    long line = 0, rows = 0;
    while (read_text_line(in, text, name, line + 1, "a text table")) {
        ++line;
        if (const auto hash = text.find('#'); hash != std::string::npos) text.erase(hash);
        if (text.find_first_not_of(" \t\r\v\f") == std::string::npos) continue;
        if (++rows > max_text_rows) throw Error("more than 10^6 rows", name, line);
        row(text, line);
    }
}

}  // namespace shapesim
