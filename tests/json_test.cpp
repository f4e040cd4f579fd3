// The one JSON reading vocabulary: every message names the input and the JSON pointer, says what
// was wanted and shows what was there.
#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin::json_reader {
namespace {

using nlohmann::json;

template <class F>
std::string error_of(F&& read) {
  try {
    read();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

const Location kRoot{"profiles/x.json", ""};

TEST(JsonReader, MessagesNameSourcePointerWantAndGot) {
  const json doc = json::parse(R"({"effects": [{"sigma_m": "0.01"}]})");
  const Location at = kRoot.child("effects").child(0).child("sigma_m");
  EXPECT_EQ(error_of([&] {
              read_number(doc["effects"][0]["sigma_m"], at, Range{0, 1});
            }),
            "profiles/x.json: /effects/0/sigma_m: must be a number in [0, 1], got a string \"0.01\"");
  EXPECT_EQ(error_of([&] {
              read_number(json(2.5), at, Range{0, 1, false, true});
            }),
            "profiles/x.json: /effects/0/sigma_m: must be in [0, 1), got 2.5");
  EXPECT_EQ(error_of([&] {
              read_string(json::array({1, 2}), kRoot);
            }),
            "profiles/x.json: /: must be a string, got an array of 2");
}

TEST(JsonReader, IntegersMayBeWrittenAsWholeFloats) {
  EXPECT_EQ(read_integer(json(1024.0), kRoot, 0, 4096), 1024);
  EXPECT_EQ(read_integer(json(7u), kRoot, 0, 10), 7);
  EXPECT_EQ(error_of([&] { read_integer(json(1.5), kRoot, 0, 10); }),
            "profiles/x.json: /: must be an integer in [0, 10], got a number 1.5");
  EXPECT_EQ(error_of([&] { read_integer(json(-1), kRoot, 0, 10); }),
            "profiles/x.json: /: must be an integer in [0, 10], got a number -1");
}

TEST(JsonReader, NumbersAreFiniteAndCounted) {
  EXPECT_EQ(read_numbers(json::array({1, 2}), kRoot, Range{0, 5}, 2), (std::vector<double>{1, 2}));
  EXPECT_EQ(error_of([&] {
              read_numbers(json::array({1, 2, 3}), kRoot, Range{0, 5}, 2);
            }),
            "profiles/x.json: /: must be 2 numbers in [0, 5], got an array of 3");
  EXPECT_EQ(error_of([&] {
              read_numbers(json::array({1, 9}), kRoot, Range{0, 5});
            }),
            "profiles/x.json: /1: must be in [0, 5], got 9");
}

TEST(ObjectReader, UnknownKeysAreErrorsUnlessKept) {
  const json object = json::parse(R"({"min_m": 0.3, "max_rnage_m": 100})");
  EXPECT_EQ(error_of([&] {
              ObjectReader(object, kRoot, {"min_m", "max_m"}, UnknownKeys::kReject, "range_limits");
            }),
            "profiles/x.json: /max_rnage_m: unknown key of range_limits; allowed keys here: min_m, max_m");
  const ObjectReader kept(object, kRoot, {"min_m"}, UnknownKeys::kKeep);
  EXPECT_NE(kept.find("min_m"), nullptr);
  EXPECT_EQ(kept.find("max_m"), nullptr);
  EXPECT_EQ(error_of([&] { kept.at("max_m", "a number"); }), "profiles/x.json: /max_m: missing (expected a number)");
  EXPECT_EQ(error_of([&] { ObjectReader(json(3), kRoot, {}); }),
            "profiles/x.json: /: must be an object, got a number 3");
}

TEST(JsonReader, PointersEscapeTheirTokens) {
  EXPECT_EQ(kRoot.child("a/b").child("c~d").to_string(), "profiles/x.json: /a~1b/c~0d");
  EXPECT_EQ(describe(json(nullptr)), "null");
  EXPECT_EQ(describe(json::object()), "an object");
  EXPECT_EQ(format_number(1e-6), "1e-06");
}

}  // namespace
}  // namespace lidartwin::json_reader
