// jsonl: line counting, schema checks, typed accessors with file:line: field: errors, and a
// writer that refuses NaN and notices a failed stream.
#include "shapesim/jsonl.hpp"
#include "shapesim/rng.hpp"

#include <ext/stdio_filebuf.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <csignal>
#include <limits>
#include <sstream>
#include <unistd.h>

using namespace shapesim;

namespace {
const std::vector<std::string> source_schema = {"shapesim.source/1"};

// The Error thrown by reading every record of `text` (fails the test if none is thrown).
Error read_error(const std::string& text, std::vector<std::string> schemas = source_schema) {
    std::istringstream in(text);
    JsonlReader reader(in, "cat.jsonl", std::move(schemas));
    Json record;
    try {
        while (reader.next(record)) {
        }
    } catch (const Error& e) {
        return e;
    }
    ADD_FAILURE() << "expected an Error reading: " << text;
    return Error("none");
}

// A record type for next_record: reads one required positive number.
struct Beta {
    double beta = 0.0;
    static Beta from_json(const Json& j) {
        Beta b{required_double(j, "beta")};
        if (!(b.beta > 0)) throw Error("must be > 0, got -0.3", {}, 0, "beta");
        return b;
    }
};
}  // namespace

TEST(JsonlReader, ReadsRecordsCountingAndSkippingBlankLines) {
    std::istringstream in(
        "{\"schema\": \"shapesim.source/1\", \"id\": \"1\"}\n"
        "\n"
        "   \n"
        "{\"schema\": \"shapesim.source/1\", \"id\": \"2\", \"new_field\": [1, 2]}\r\n"
        "{\"schema\": \"shapesim.source/1\", \"id\": \"3\"}");  // no final newline
    JsonlReader reader(in, "cat.jsonl", source_schema);
    Json record;
    ASSERT_TRUE(reader.next(record));
    EXPECT_EQ(reader.line(), 1);
    EXPECT_EQ(record["id"], "1");
    ASSERT_TRUE(reader.next(record));
    EXPECT_EQ(reader.line(), 4);  // the blank lines count
    EXPECT_EQ(record["new_field"], Json::array({1, 2}));
    ASSERT_TRUE(reader.next(record));
    EXPECT_EQ(reader.line(), 5);
    EXPECT_FALSE(reader.next(record));
    EXPECT_FALSE(reader.next(record));
}

TEST(JsonlReader, FieldOrderIsKept) {
    std::istringstream in("{\"schema\": \"s/1\", \"id\": \"a\", \"zz\": 1, \"aa\": 2}\n");
    JsonlReader reader(in, "-", {});
    Json record;
    ASSERT_TRUE(reader.next(record));
    EXPECT_EQ(record.dump(), R"({"schema":"s/1","id":"a","zz":1,"aa":2})");
}

TEST(JsonlReader, MalformedLineNamesFileLineAndColumn) {
    const Error e = read_error(
        "{\"schema\": \"shapesim.source/1\"}\n"
        "{\"schema\": \"shapesim.source/1\", \"x\": 1.5,, }\n");
    EXPECT_EQ(e.file(), "cat.jsonl");
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(e.message().find("invalid JSON at column"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("cat.jsonl:2: invalid JSON at column", 0), 0u)
        << e.what();
    EXPECT_EQ(std::string(e.what()).find("json.exception"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("line 1"), std::string::npos) << e.what();
}

TEST(JsonlReader, TruncatedLastLine) {
    const Error e = read_error(
        "{\"schema\": \"shapesim.source/1\", \"id\": \"1\"}\n"
        "{\"schema\": \"shapesim.source/1\", \"id\": \"2\", \"x\": 3.");
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(e.message().find("invalid JSON"), std::string::npos) << e.what();
}

TEST(JsonlReader, NumberOverflowAndNanLiteralAreInvalidJson) {
    EXPECT_EQ(read_error("{\"schema\": \"shapesim.source/1\", \"x\": 1e999}\n").line(), 1);
    const Error e = read_error("\n{\"schema\": \"shapesim.source/1\", \"x\": NaN}\n");
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(e.message().find("invalid JSON"), std::string::npos) << e.what();
}

TEST(JsonlReader, NonObjectLine) {
    const Error e = read_error("[1, 2]\n");
    EXPECT_EQ(std::string(e.what()), "cat.jsonl:1: expected a JSON object, got array");
}

// 10⁵ nested brackets (a fuzzer's favourite) are refused in one line, not by a stack
// overflow in the message's rendering of the value.
TEST(JsonlReader, DeeplyNestedLineIsRefusedCleanly) {
    const std::string deep = std::string(100000, '[') + std::string(100000, ']') + "\n";
    EXPECT_EQ(std::string(read_error(deep).what()), "cat.jsonl:1: expected a JSON object, got array");
    const std::string in_schema =
        "{\"schema\": " + std::string(100000, '[') + std::string(100000, ']') + "}\n";
    EXPECT_EQ(std::string(read_error(in_schema).what()),
              "cat.jsonl:1: schema: expected a string, got array");
}

TEST(JsonDocument, SyntaxErrorNamesLineAndColumn) {
    try {
        parse_json_document("{\n  \"a\": 1,\n  \"b\": NaN\n}\n", "model.json");
        ADD_FAILURE() << "no Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()).rfind("model.json: invalid JSON at line 3, column 8: ", 0),
                  0u)
            << e.what();
    }
    EXPECT_EQ(parse_json_document("[1, 2]", "x").size(), 2u);
}

TEST(JsonlReader, WrongMissingOrMistypedSchema) {
    Error e = read_error("{\"schema\": \"shapesim.shapelet/1\", \"id\": \"1\"}\n");
    EXPECT_EQ(std::string(e.what()),
              "cat.jsonl:1: schema: expected \"shapesim.source/1\", got \"shapesim.shapelet/1\"");
    e = read_error("{\"id\": \"1\"}\n");
    EXPECT_EQ(std::string(e.what()),
              "cat.jsonl:1: schema: missing (expected \"shapesim.source/1\")");
    e = read_error("{\"schema\": 1}\n");
    EXPECT_EQ(e.field(), "schema");
    e = read_error("{\"schema\": \"c/1\"}\n", {"a/1", "b/1"});
    EXPECT_EQ(e.message(), "expected \"a/1\" or \"b/1\", got \"c/1\"");
}

TEST(JsonlReader, SchemaIsCheckedOnEveryLine) {
    const Error e = read_error(
        "{\"schema\": \"shapesim.source/1\"}\n"
        "{\"schema\": \"shapesim.source/1\"}\n"
        "{\"schema\": \"shapesim.object/1\"}\n");
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.field(), "schema");
}

TEST(JsonlReader, NextRecordPlacesFieldErrors) {
    std::istringstream in(
        "{\"schema\": \"s/1\", \"beta\": 0.5}\n"
        "{\"schema\": \"s/1\", \"beta\": -0.3}\n");
    JsonlReader reader(in, "shapelets.jsonl", {"s/1"});
    Beta b;
    ASSERT_TRUE(reader.next_record(b));
    EXPECT_EQ(b.beta, 0.5);
    try {
        reader.next_record(b);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), "shapelets.jsonl:2: beta: must be > 0, got -0.3");
    }
}

TEST(JsonlReader, MissingFileIsAnError) {
    try {
        JsonlReader reader("/nonexistent/cat.jsonl", {});
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  "/nonexistent/cat.jsonl: cannot open: No such file or directory");
    }
}

TEST(JsonlAccessors, TypedFieldsAndTheirErrors) {
    const Json j = Json::parse(
        R"({"d": 1.5, "i": 7, "f": 4.0, "s": "abc", "n": null, "a": [1], "o": {"k": 1},
            "big": 1e12, "neg": -3, "flags": ["converged", "edge"], "bad_flags": ["ok", 3]})");
    EXPECT_EQ(required_double(j, "d"), 1.5);
    EXPECT_EQ(required_double(j, "i"), 7.0);  // an integer is a number
    EXPECT_EQ(required_int(j, "i"), 7);
    EXPECT_EQ(required_int(j, "f"), 4);  // integral float accepted
    EXPECT_EQ(required_int(j, "neg"), -3);
    EXPECT_EQ(required_string(j, "s"), "abc");
    EXPECT_EQ(required_array(j, "a").size(), 1u);
    EXPECT_EQ(required_object(j, "o")["k"], 1);
    EXPECT_FALSE(optional_double(j, "missing"));
    EXPECT_FALSE(optional_double(j, "n"));  // null = not measured
    EXPECT_FALSE(optional_string(j, "n"));
    EXPECT_EQ(optional_array(j, "n"), nullptr);
    EXPECT_EQ(*optional_int(j, "i"), 7);
    EXPECT_EQ(optional_strings(j, "flags"), (std::vector<std::string>{"converged", "edge"}));
    EXPECT_TRUE(optional_strings(j, "missing").empty());

    const auto error_of = [&](auto&& read) -> std::string {
        try {
            read();
        } catch (const Error& e) {
            return e.what();
        }
        return "no error";
    };
    EXPECT_EQ(error_of([&] { required_double(j, "missing"); }), "missing: missing");
    EXPECT_EQ(error_of([&] { required_double(j, "n"); }), "n: missing");
    EXPECT_EQ(error_of([&] { required_double(j, "s"); }),
              "s: expected a number, got string \"abc\"");
    EXPECT_EQ(error_of([&] { required_int(j, "d"); }), "d: expected an integer, got number 1.5");
    EXPECT_EQ(error_of([&] { required_int(j, "big"); }),
              "big: expected an integer, got number 1000000000000.0");
    EXPECT_EQ(error_of([&] { required_string(j, "i"); }), "i: expected a string, got number 7");
    EXPECT_EQ(error_of([&] { required_array(j, "o"); }), "o: expected an array, got object");
    EXPECT_EQ(error_of([&] { required_object(j, "a"); }), "a: expected an object, got array");
    EXPECT_EQ(error_of([&] { optional_strings(j, "bad_flags"); }),
              "bad_flags[1]: expected a string, got number 3");
    EXPECT_EQ(error_of([&] { as_double(Json(std::nan("")), "x"); }), "x: must be finite");
    EXPECT_EQ(error_of([&] { as_double(Json(INFINITY), "x"); }), "x: must be finite");
    EXPECT_EQ(error_of([&] { required_int(Json::parse(R"({"k": 4294967296})"), "k"); }),
              "k: integer out of range, got 4294967296");
}

TEST(JsonlWriter, WritesOneFlushedLinePerRecordKeepingOrder) {
    std::ostringstream out;
    JsonlWriter writer(out, "-");
    Json record;
    record["schema"] = "shapesim.source/1";
    record["id"] = "7";
    record["x"] = 0.1;
    record["y"] = 1.0 / 3.0;
    writer.write(record);
    writer.write(record);
    EXPECT_EQ(writer.count(), 2);
    const std::string line =
        R"({"schema":"shapesim.source/1","id":"7","x":0.1,"y":0.3333333333333333})";
    EXPECT_EQ(out.str(), line + "\n" + line + "\n");
    // Shortest round-trip doubles: reading the line back gives the same numbers.
    EXPECT_EQ(Json::parse(line)["y"].get<double>(), 1.0 / 3.0);
}

TEST(JsonlWriter, RefusesNanAndInfNamingTheFieldAndWritesNothing) {
    std::ostringstream out;
    JsonlWriter writer(out, "objects.jsonl");
    writer.write(Json{{"schema", "s/1"}, {"id", "1"}});
    Json bad{{"schema", "s/1"}, {"id", "2"}, {"mag", std::nan("")}};
    try {
        writer.write(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  "objects.jsonl:2: mag: is NaN or infinite, which JSON cannot hold");
    }
    bad = Json{{"schema", "s/1"}, {"psf", {{"coeffs", {{1.0, 0.0}, {INFINITY, 0.0}}}}}};
    try {
        writer.write(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "psf.coeffs[1][0]");
    }
    EXPECT_EQ(out.str(), "{\"schema\":\"s/1\",\"id\":\"1\"}\n");
    EXPECT_EQ(writer.count(), 1);
    EXPECT_THROW(writer.write(Json::array({1})), Error);
}

TEST(JsonlWriter, FullDiskIsAnError) {
    std::ofstream full("/dev/full");
    ASSERT_TRUE(full.is_open());
    JsonlWriter writer(full, "/dev/full");
    try {
        writer.write(Json{{"schema", "s/1"}});
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), "/dev/full");
        EXPECT_NE(e.message().find("write failed"), std::string::npos) << e.what();
    }
}

TEST(JsonlWriter, ClosedPipeIsAnError) {
    // As under app::run_main: SIGPIPE ignored, so the write fails with EPIPE.
    const auto previous = std::signal(SIGPIPE, SIG_IGN);
    int fds[2];
    ASSERT_EQ(pipe(fds), 0);
    close(fds[0]);  // the reader went away
    {
        __gnu_cxx::stdio_filebuf<char> buf(fds[1], std::ios::out);
        std::ostream out(&buf);
        JsonlWriter writer(out, "-");
        try {
            writer.write(Json{{"schema", "s/1"}, {"id", "1"}});
            FAIL() << "expected Error";
        } catch (const Error& e) {
            EXPECT_EQ(std::string(e.what()), "-: write failed: Broken pipe");
        }
    }  // the filebuf closes fds[1]
    std::signal(SIGPIPE, previous);
}

TEST(Jsonl, UnknownFieldsRoundTripByteForByte) {
    const std::string line =
        R"({"schema":"shapesim.source/1","id":"9","x":12.25,"future":{"a":[1,2.5,"z"]},"n":null})";
    std::istringstream in(line + "\n");
    JsonlReader reader(in, "-", source_schema);
    Json record;
    ASSERT_TRUE(reader.next(record));
    std::ostringstream out;
    JsonlWriter(out, "-").write(record);
    EXPECT_EQ(out.str(), line + "\n");
}

namespace {

// What nlohmann makes of `text`: its dump, or "error".
std::string nlohmann_dump(const std::string& text) {
    try {
        return Json::parse(text).dump();
    } catch (const nlohmann::json::exception&) {
        return "error";
    }
}

// A random JSON text: nested values, numbers in every JSON form (integers past 64 bits and
// past double range among them), strings with escapes, and now and then a corruption.
void random_json(RandomStream& r, int depth, std::string& out) {
    const auto pick = r.uniform_index(depth > 3 ? 6 : 8);
    static const char* numbers[] = {"0", "-0", "7", "-12", "3.25", "-0.0", "1e5", "2E-3", "-4.5e+2",
                                    "18446744073709551615", "18446744073709551616",
                                    "-9223372036854775808", "-9223372036854775809",
                                    "123456789012345678901234567890", "1e400", "-1e-400", "4.9e-324",
                                    "0.1", "1.7976931348623157e308", "01", "1.", ".5", "-", "1e", "+1"};
    static const char* strings[] = {"\"\"", "\"g12\"", "\"a\\\"b\"", "\"tab\\there\"", "\"\\/\\\\\"",
                                    "\"\\u00e9\"", "\"\xc3\xa9\"", "\"bad\\x\"", "\"\x01\"", "\"open"};
    switch (pick) {
    case 0: out += numbers[r.uniform_index(std::size(numbers))]; break;
    case 1: out += std::to_string(r.uniform(-1e6, 1e6)); break;
    case 2: {
        char text[32];
        std::snprintf(text, sizeof text, "%.17g", r.gaussian() * std::pow(10.0, r.uniform(-30, 30)));
        out += text;
        break;
    }
    case 3: out += strings[r.uniform_index(std::size(strings))]; break;
    case 4: out += std::array<const char*, 4>{"true", "false", "null", "nul"}[r.uniform_index(4)]; break;
    case 5: out += std::to_string(std::int64_t(r.next_u64() >> r.uniform_index(64))); break;
    case 6:
    case 7: {
        const bool object = pick == 6;
        out += object ? "{" : "[ ";
        const auto n = r.uniform_index(5);
        for (std::uint64_t k = 0; k < n; ++k) {
            if (k) out += r.uniform_index(50) ? "," : "";
            if (object) out += std::array<const char*, 4>{"\"a\"", "\"b\"", "\"schema\"", "\"c d\""}[r.uniform_index(4)] + std::string(r.coin() ? ":" : " : ");
            random_json(r, depth + 1, out);
        }
        out += object ? "}" : " ]";
    }
    }
    if (r.uniform_index(200) == 0) out += "x";  // trailing garbage
}

}  // namespace

// The fast parser either declines or gives exactly nlohmann's value, integers as integers
// (the dumps differ between 1 and 1.0); it declines wherever nlohmann errs.
TEST(JsonFast, EqualsNlohmannOrDeclines) {
    RandomStream r(5, 1, "json texts");
    long taken = 0, declined = 0;
    for (int i = 0; i < 20000; ++i) {
        std::string text;
        if (r.coin()) text += " ";
        random_json(r, 0, text);
        if (r.coin()) text += "\t\r";
        const auto fast = parse_json_fast(text);
        const std::string expect = nlohmann_dump(text);
        if (fast) {
            ASSERT_EQ(fast->dump(), expect) << text;
            ++taken;
        } else {
            ++declined;
        }
    }
    EXPECT_GT(taken, 12000);
    EXPECT_GT(declined, 500);
    // Typed as nlohmann types them: unsigned, signed, float.
    const auto j = parse_json_fast(R"({"u":3,"s":-3,"z":-0,"f":3.0,"big":18446744073709551615})");
    ASSERT_TRUE(j);
    EXPECT_TRUE((*j)["u"].is_number_unsigned());
    EXPECT_TRUE((*j)["s"].is_number_integer() && !(*j)["s"].is_number_unsigned());
    EXPECT_TRUE((*j)["z"].is_number_integer() && !(*j)["z"].is_number_unsigned());
    EXPECT_TRUE((*j)["f"].is_number_float());
    EXPECT_EQ((*j)["big"].get<std::uint64_t>(), 18446744073709551615ULL);
    EXPECT_EQ(j->dump(), Json::parse(R"({"u":3,"s":-3,"z":-0,"f":3.0,"big":18446744073709551615})").dump());
    for (const char* declines : {"{\"a\":1,\"a\":2}", "\"\\u0041\"", "1e999", "[1,]", "{\"a\" 1}", "",
                                 "\xef\xbb\xbf{}", "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]"})
        EXPECT_FALSE(parse_json_fast(declines)) << declines;
}
