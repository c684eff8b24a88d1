#include "app/run_main.hpp"

#include "shapesim/atomic_file.hpp"

#include "app/options.hpp"
#include "shapesim/error.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <new>

namespace shapesim::app {

namespace {
// One line on stderr, written in one call.
void say(const std::string& program, const std::string& message) {
    const std::string line = program + ": " + message + "\n";
    std::fwrite(line.data(), 1, line.size(), stderr);
    std::fflush(stderr);
}

// Data written to stdout but still buffered must reach it, or the run failed.
bool flush_stdout(std::string& why) {
    errno = 0;
    std::cout.flush();
    const bool ok = std::cout.good() && std::fflush(stdout) == 0 && !std::ferror(stdout);
    if (!ok) why = errno ? std::strerror(errno) : "unknown error";
    return ok;
}
}  // namespace

int run_main(int argc, const char* const argv[], const std::string& program,
             const ProgramBody& body) {
    std::signal(SIGPIPE, SIG_IGN);
    remove_temporaries_on_signals(program);
    int code = 1;
    try {
        code = body(argc, argv);
    } catch (const Error& e) {
        say(program, e.where_what());
        return 1;
    } catch (const po::error& e) {
        say(program, std::string(e.what()) + " (see --help)");
        return 2;
    } catch (const std::bad_alloc&) {
        say(program, "out of memory");
        return 1;
    } catch (const std::exception& e) {
        say(program, std::string("internal error: ") + e.what());
        return 1;
    } catch (...) {
        say(program, "internal error: unknown exception");
        return 1;
    }
    std::string why;
    if (!flush_stdout(why)) {
        say(program, "-: write failed: " + why);
        return 1;
    }
    return code;
}

int run_placeholder(int argc, const char* const argv[], const std::string& program,
                    const std::string& description) {
    return run_main(argc, argv, program, [&](int n, const char* const args[]) {
        ProgramOptions options(program, "[OPTION]...",
                               description +
                                   "\n\nNOT IMPLEMENTED YET: this program is a placeholder and "
                                   "its issue is open.\nOnly --help and --version work; any "
                                   "other invocation exits with status 2.",
                               Common::none);
        options.hidden().add_options()("args", po::value<std::vector<std::string>>());
        options.positional("args", -1);
        options.allow_unregistered();
        if (!options.parse(n, args)) return 0;
        throw po::error("not implemented yet");
    });
}

}  // namespace shapesim::app
