// libFuzzer harness: the record readers (issue 15). The input is read as a JSON-lines stream
// of any schema, each record converted by every record type (and to a model where there is
// one), then as objects read whole (render's path), then as one JSON document (a morphology
// model). A shapesim::Error is a clean refusal;
// anything else (another exception, a crash, a sanitizer report, a leak) is a bug.
#include "refused_or_read.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/records.hpp"

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

using namespace shapesim;
using shapesim::fuzz::refused_or_read;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    refused_or_read([&] {
        std::istringstream in(text);
        JsonlReader reader(in, "fuzz.jsonl", {});
        Json record;
        while (reader.next(record)) {
            refused_or_read([&] { SourceRecord::from_json(record); });
            refused_or_read([&] { ShapeletRecord::from_json(record).to_model(); });
            refused_or_read([&] { ObjectRecord::from_json(record).to_model(1.0, 1.0); });
            refused_or_read([&] { MorphRecord::from_json(record); });
            refused_or_read([&] { NoiseRecord::from_json(record); });
        }
    });
    // Objects as render reads them: "coeffs" straight into numbers (NumberPairs).
    refused_or_read([&] {
        std::istringstream in(text);
        JsonlReader(in, "fuzz.jsonl", {ObjectRecord::schema}).read_all<ObjectRecord>(1);
    });
    refused_or_read([&] { Morphology::from_json(parse_json_document(text, "fuzz.json")); });
    return 0;
}
