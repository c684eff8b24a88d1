// The one wrapper around every program's main (STYLE (b) "Errors and exit codes").
//
// run_main runs a program's body and maps what escapes it to one stderr line and an exit code:
//   shapesim::Error       `program: file:line: field: message`            exit 1 (bad data,
//                                                                          runtime failure)
//   po::error (usage)     `program: message (see --help)`                  exit 2
//   std::bad_alloc        `program: out of memory`                         exit 1
//   other std::exception  `program: internal error: …`                     exit 1 (a bug)
// SIGPIPE is ignored, so writing to a closed pipe fails with EPIPE and surfaces as an Error
// ("-: write failed: Broken pipe", exit 1) instead of a silent death by signal. After the body
// returns, stdout is flushed and checked, so a write error in buffered output is not lost.
#pragma once

#include <functional>
#include <string>

namespace shapesim::app {

/// The body of a program: parses argv itself, returns the exit code (0 on success).
using ProgramBody = std::function<int(int argc, const char* const argv[])>;

/// Run `body` and map exceptions to exit codes as above; `program` prefixes every message.
int run_main(int argc, const char* const argv[], const std::string& program,
             const ProgramBody& body);

/// The main of a program that is not implemented yet: --help (purpose from `description`,
/// marked not implemented) and --version work; any other invocation prints
/// `program: not implemented yet (see --help)` and exits 2.
int run_placeholder(int argc, const char* const argv[], const std::string& program,
                    const std::string& description);

}  // namespace shapesim::app
