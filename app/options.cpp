#include "shapesim/version.hpp"
#include "app/options.hpp"

#include "shapesim/error.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iostream>
#include <thread>


namespace shapesim::app {

std::string double_text(double v) {
    char buf[32];
    const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
    return std::string(buf, end);
}

namespace {

// Options about the run itself, not settings: never read from --config nor printed by
// --print-params.
bool is_meta(const std::string& name) {
    return name == "help" || name == "version" || name == "config" || name == "print-params";
}

// A stored option value as config-file text, one entry per value (vectors give several).
std::vector<std::string> value_texts(const boost::any& v) {
    using boost::any_cast;
    if (const auto* s = any_cast<std::string>(&v)) return {*s};
    if (const auto* b = any_cast<bool>(&v)) return {*b ? "true" : "false"};
    if (const auto* d = any_cast<double>(&v)) return {double_text(*d)};
    if (const auto* f = any_cast<float>(&v)) return {double_text(*f)};
    if (const auto* i = any_cast<int>(&v)) return {std::to_string(*i)};
    if (const auto* l = any_cast<long>(&v)) return {std::to_string(*l)};
    if (const auto* ll = any_cast<long long>(&v)) return {std::to_string(*ll)};
    if (const auto* u = any_cast<unsigned>(&v)) return {std::to_string(*u)};
    if (const auto* ul = any_cast<unsigned long>(&v)) return {std::to_string(*ul)};
    if (const auto* vs = any_cast<std::vector<std::string>>(&v)) return *vs;
    if (const auto* vd = any_cast<std::vector<double>>(&v)) {
        std::vector<std::string> out;
        for (double d : *vd) out.push_back(double_text(d));
        return out;
    }
    if (const auto* vi = any_cast<std::vector<int>>(&v)) {
        std::vector<std::string> out;
        for (int i : *vi) out.push_back(std::to_string(i));
        return out;
    }
    if (const auto* vl = any_cast<std::vector<long>>(&v)) {
        std::vector<std::string> out;
        for (long l : *vl) out.push_back(std::to_string(l));
        return out;
    }
    throw Error("--print-params: an option has a type it cannot print");
}

std::uint64_t parse_seed(const std::string& text) {
    std::uint64_t seed = 0;
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, seed);
    if (text.empty() || ec != std::errc() || ptr != end)
        throw po::error("--seed: must be an integer in [0, 2^64 - 1], got '" + text + "'");
    return seed;
}

}  // namespace

std::string version_line(const std::string& program) {
    return program + " (shapesim) " + shapesim::version();
}

ProgramOptions::ProgramOptions(std::string program, std::string synopsis, std::string description,
                               unsigned common)
    : program_(std::move(program)),
      synopsis_(std::move(synopsis)),
      description_(std::move(description)) {
    declare_common(common);
}

void ProgramOptions::declare_common(unsigned common) {
    auto add = common_options_.add_options();
    add("help,h", "print this help and exit");
    add("version", "print the version and exit");
    if (common & Common::output)
        add("output,o", po::value<std::string>()->value_name("FILE"),
            "write the output to FILE instead of stdout (as FILE.tmp.<pid>, renamed when "
            "complete)");
    if (common & Common::quiet) add("quiet,q", po::bool_switch(), "print only errors on stderr");
    if (common & Common::verbose)
        add("verbose,v", po::bool_switch(), "also print one line per object on stderr");
    if (common & Common::threads)
        add("threads,j",
            po::value<int>()->value_name("N")->default_value(1)->notifier(
                in_range("threads", 0, 4096)),
            "worker threads (0 = one per hardware thread); results do not depend on it");
    if (common & Common::seed)
        add("seed", po::value<std::string>(&seed_text_)->value_name("N")->default_value("0"),
            "run seed (unsigned 64-bit); every random stream is keyed by (seed, object id)");
    if (common & Common::like)
        add("like", po::value<std::string>()->value_name("IMAGE"),
            "field geometry (size, pixel scale, WCS) of this FITS image");
    if (common & Common::config)
        add("config", po::value<std::string>()->value_name("FILE"),
            "read further options from FILE (`name = value` lines); the command line wins");
    if (common & Common::print_params)
        add("print-params", "print the effective parameters in --config syntax and exit");
}

po::options_description& ProgramOptions::group(const std::string& title) {
    for (auto& [name, description] : groups_)
        if (name == title) return *description;
    groups_.emplace_back(title, std::make_unique<po::options_description>(title));
    return *groups_.back().second;
}

void ProgramOptions::positional(const std::string& name, int max_count) {
    positional_.add(name.c_str(), max_count);
}

po::options_description ProgramOptions::all_options(bool for_config) const {
    po::options_description all;
    for (const auto& group : groups_) all.add(*group.second);
    for (const auto& option : common_options_.options())
        if (!for_config || !is_meta(option->long_name())) all.add(option);
    all.add(hidden_);
    return all;
}

void ProgramOptions::alias(const std::string& old_name, const std::string& name) {
    aliases_.emplace_back(old_name, name);
}

std::string ProgramOptions::renamed(const std::string& name) {
    for (const auto& [old_name, new_name] : aliases_) {
        if (name != old_name) continue;
        if (std::find(aliases_used_.begin(), aliases_used_.end(),
                      std::pair(old_name, new_name)) == aliases_used_.end())
            aliases_used_.emplace_back(old_name, new_name);
        return new_name;
    }
    return name;
}

namespace {

// A negative number ("-0.02", "-1e-3") is a value, not a short option: Boost would read
// "--shear 0.01 -0.02" as an unknown option -0; as a value token, a multitoken option takes it
// and a single-valued one (--kappa -0.1) too.
std::vector<po::option> negative_numbers(std::vector<std::string>& args) {
    std::vector<po::option> values;
    auto is_negative_number = [](const std::string& a) {
        if (a.size() < 2 || a[0] != '-' || !(std::isdigit((unsigned char)a[1]) || a[1] == '.'))
            return false;
        char* end = nullptr;
        std::strtod(a.c_str(), &end);
        return end == a.c_str() + a.size();
    };
    while (!args.empty() && is_negative_number(args.front())) {
        po::option value;
        value.position_key = 0;
        value.value.push_back(args.front());
        value.original_tokens.push_back(args.front());
        values.push_back(std::move(value));
        args.erase(args.begin());
    }
    return values;
}

}  // namespace

bool ProgramOptions::parse(int argc, const char* const argv[]) {
    // Old names become new ones before Boost sees them (so they need no typed declaration of
    // their own); after "--" every argument is a value.
    std::vector<std::string> args(argv, argv + argc);
    for (std::size_t i = 1; i < args.size() && args[i] != "--"; ++i) {
        if (args[i].rfind("--", 0) != 0) continue;
        const std::size_t eq = args[i].find('=');
        const std::string name = args[i].substr(2, eq == std::string::npos ? eq : eq - 2);
        const std::string to = renamed(name);
        if (to != name) args[i] = "--" + to + (eq == std::string::npos ? "" : args[i].substr(eq));
    }
    std::vector<const char*> arg_pointers;
    for (const std::string& a : args) arg_pointers.push_back(a.c_str());

    const po::options_description all = all_options(false);
    auto parser = po::command_line_parser(int(arg_pointers.size()), arg_pointers.data())
                      .options(all)
                      .positional(positional_)
                      .extra_style_parser(negative_numbers);
    if (allow_unregistered_) parser.allow_unregistered();
    const po::parsed_options parsed = parser.run();
    if (allow_unregistered_)
        unrecognized_ = po::collect_unrecognized(parsed.options, po::include_positional);
    po::store(parsed, values_);

    // --help and --version win over everything else, including missing required options.
    if (values_.count("help")) {
        std::cout << help();
        return false;
    }
    if (values_.count("version")) {
        std::cout << version_line(program_) << '\n';
        return false;
    }
    if (values_.count("config")) read_config(values_["config"].as<std::string>());
    po::notify(values_);
    resolve_common();
    if (common_.verbosity != Verbosity::quiet)
        for (const auto& [old_name, new_name] : aliases_used_)
            std::cerr << program_ << ": warning: --" << old_name << " is now --" << new_name
                      << "; the old name goes in a later release\n";
    if (values_.count("print-params")) {
        std::cout << params();
        return false;
    }
    return true;
}

void ProgramOptions::read_config(const std::string& path) {
    std::ifstream file(path);
    if (!file) throw Error(std::string("cannot open: ") + std::strerror(errno), path);
    // `old = value` lines take the new name, as on the command line.
    std::string text, line;
    while (std::getline(file, line)) {
        const std::size_t start = line.find_first_not_of(" \t");
        const std::size_t eq = line.find('=');
        if (start != std::string::npos && eq != std::string::npos && line[start] != '#') {
            std::size_t end = eq;
            while (end > start && (line[end - 1] == ' ' || line[end - 1] == '\t')) --end;
            const std::string name = line.substr(start, end - start);
            const std::string to = renamed(name);
            if (to != name) line = line.substr(0, start) + to + line.substr(end);
        }
        text += line + "\n";
    }
    std::istringstream in(text);
    try {
        po::store(po::parse_config_file(in, all_options(true)), values_);
    } catch (const po::error& e) {
        throw po::error(path + ": " + e.what());
    }
}

void ProgramOptions::resolve_common() {
    const auto flag = [&](const char* name) {
        return values_.count(name) && values_[name].as<bool>();
    };
    if (values_.count("output")) common_.output = values_["output"].as<std::string>();
    if (flag("quiet") && flag("verbose"))
        throw po::error("--quiet and --verbose exclude each other");
    common_.verbosity = flag("quiet")     ? Verbosity::quiet
                        : flag("verbose") ? Verbosity::verbose
                                          : Verbosity::normal;
    if (values_.count("threads")) {
        common_.threads = values_["threads"].as<int>();
        if (common_.threads == 0) common_.threads = int(std::thread::hardware_concurrency());
        if (common_.threads <= 0) common_.threads = 1;
    }
    if (values_.count("seed")) {
        common_.seed = parse_seed(seed_text_);
        common_.seed_given = given("seed");
    }
    if (values_.count("like")) common_.like = values_["like"].as<std::string>();
    if (values_.count("config")) common_.config = values_["config"].as<std::string>();
}

bool ProgramOptions::given(const std::string& name) const {
    return values_.count(name) && !values_[name].defaulted();
}

std::string shortest_number(double value) {
    char text[32];
    for (int digits = 1; digits <= 17; ++digits) {
        std::snprintf(text, sizeof text, "%.*g", digits, value);
        if (std::strtod(text, nullptr) == value) break;
    }
    return text;
}

std::string defaults_as_written(const std::string& help) {
    // Boost prints a double default with 17 digits: (=0.96999999999999997). Print the
    // shortest text that reads back as the same double, (=0.97); when the description goes on
    // on the same line, pad so its column stays where Boost put it. (A hand scan: std::regex
    // trips GCC 12's -Wmaybe-uninitialized under the sanitizers.)
    std::string out;
    std::size_t from = 0;
    for (std::size_t at = help.find("(="); at != std::string::npos; at = help.find("(=", at + 2)) {
        // "(=" [-] digits "." ≥ 8 digits [e[±]digits] ")"
        std::size_t k = at + 2;
        const auto digits = [&] {
            const std::size_t start = k;
            while (k < help.size() && std::isdigit(static_cast<unsigned char>(help[k]))) ++k;
            return k - start;
        };
        if (k < help.size() && help[k] == '-') ++k;
        if (digits() == 0 || k >= help.size() || help[k] != '.') continue;
        ++k;
        if (digits() < 8) continue;
        if (k < help.size() && help[k] == 'e') {
            ++k;
            if (k < help.size() && (help[k] == '-' || help[k] == '+')) ++k;
            if (digits() == 0) continue;
        }
        if (k >= help.size() || help[k] != ')') continue;
        const std::size_t length = k + 1 - at;
        const std::string number = help.substr(at + 2, length - 3);
        std::string tidy = "(=" + shortest_number(std::strtod(number.c_str(), nullptr)) + ")";
        const std::size_t line_end = std::min(help.find('\n', at + length), help.size());
        if (help.find_first_not_of(' ', at + length) < line_end && tidy.size() < length)
            tidy += std::string(length - tidy.size(), ' ');
        out += help.substr(from, at - from) + tidy;
        from = at + length;
    }
    return out + help.substr(from);
}

std::string ProgramOptions::help() const {
    std::ostringstream s;
    s << "Usage: " << program_ << " " << synopsis_ << "\n" << description_ << "\n\n";
    for (const auto& group : groups_) s << *group.second << "\n";
    s << common_options_;
    if (!aliases_.empty()) {
        s << "\nOld option names, still accepted for this release:";
        for (const auto& [old_name, new_name] : aliases_)
            s << "\n  --" << old_name << " (now --" << new_name << ")";
        s << "\n";
    }
    if (!epilog_.empty()) s << "\n" << epilog_ << "\n";
    return defaults_as_written(s.str());
}

std::vector<std::pair<std::string, std::string>> ProgramOptions::settings() const {
    std::vector<std::pair<std::string, std::string>> out;
    const po::options_description options = all_options(true);  // outlives the loop
    for (const auto& option : options.options()) {
        const std::string name = option->long_name();
        if (!values_.count(name) || values_[name].empty()) continue;
        for (auto& text : value_texts(values_[name].value())) out.emplace_back(name, text);
    }
    return out;
}

std::string ProgramOptions::params() const {
    std::ostringstream s;
    s << "# " << version_line(program_) << "\n";
    for (const auto& [name, text] : settings()) s << name << " = " << text << "\n";
    return s.str();
}

std::vector<std::string> split_list(const std::string& list) {
    std::vector<std::string> items;
    std::string item;
    for (char c : list + ",") {
        if (c == ',') {
            if (!item.empty()) items.push_back(item);
            item.clear();
        } else if (c != ' ') {
            item += c;
        }
    }
    return items;
}

std::vector<std::pair<std::string, std::string>> named_files(const std::vector<std::string>& specs,
                                                             const std::string& option) {
    std::vector<std::pair<std::string, std::string>> out;
    for (const std::string& spec : specs) {
        const auto eq = spec.find('=');
        if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
            throw po::error("--" + option + " takes NAME=FILE, got '" + spec + "'");
        out.emplace_back(spec.substr(0, eq), spec.substr(eq + 1));
    }
    return out;
}

}  // namespace shapesim::app
