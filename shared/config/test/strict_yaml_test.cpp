#include "hq/config/strict_yaml.hpp"

#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace hq::config {
namespace {

using hq::testing::input_error_message;
using ::testing::HasSubstr;

TEST(StrictMap, ReadsTypedValuesAndKeepsDefaultsForAbsentKeys) {
  const YAML::Node node =
      YAML::Load("{gain: 2.5, count: 3, enabled: true, mode: fast, angle_deg: 90, p_m: [1, 2, 3]}");
  StrictMap map(node, "test.yaml");
  double gain = 0, absent = 7.0, angle = 0;
  int count = 0;
  bool enabled = false;
  std::string mode;
  double p[3] = {};
  map.read("gain", gain, 0.0, 10.0);
  map.read("absent", absent, 0.0, 10.0);
  map.read("count", count, 0, 5);
  map.read("enabled", enabled);
  map.read("mode", mode, {"fast", "slow"});
  map.read_deg_as_rad("angle_deg", angle, 0.0, 180.0);
  map.read_list("p_m", p, 3);
  map.finish();
  EXPECT_DOUBLE_EQ(gain, 2.5);
  EXPECT_DOUBLE_EQ(absent, 7.0);
  EXPECT_EQ(count, 3);
  EXPECT_TRUE(enabled);
  EXPECT_EQ(mode, "fast");
  EXPECT_NEAR(angle, M_PI / 2, 1e-12);
  EXPECT_DOUBLE_EQ(p[2], 3.0);
}

TEST(StrictMap, OutOfRangeNamesFileKeyValueAndExpectation) {
  const YAML::Node node = YAML::Load("{obstacles: {influence_distance_m: -1.2}}");
  StrictMap root(node, "config/onboard.yaml");
  StrictMap obstacles = root.child("obstacles");
  double d = 1.0;
  EXPECT_EQ(input_error_message([&] { obstacles.read_positive("influence_distance_m", d); }),
            "config/onboard.yaml: obstacles.influence_distance_m = -1.2, expected > 0");
}

TEST(StrictMap, RejectsUnknownKeysMissingKeysAndWrongTypes) {
  StrictMap unknown(YAML::Load("{gain: 1, gian: 2}"), "a.yaml");
  double gain = 0;
  unknown.read("gain", gain, 0, 10);
  EXPECT_THAT(input_error_message([&] { unknown.finish(); }),
              HasSubstr("a.yaml: gian is not a known key"));

  StrictMap missing(YAML::Load("{}"), "b.yaml");
  EXPECT_THAT(input_error_message([&] { missing.require("mass_kg", gain, 0, 10); }),
              HasSubstr("b.yaml: mass_kg is missing"));

  StrictMap wrong(YAML::Load("{mass_kg: heavy, n: 2.5, flag: maybe, list: [1, 2]}"), "c.yaml");
  int n = 0;
  bool flag = false;
  double list[3];
  EXPECT_THAT(input_error_message([&] { wrong.read("mass_kg", gain, 0, 10); }),
              HasSubstr("c.yaml: mass_kg = heavy, expected a number"));
  EXPECT_THAT(input_error_message([&] { wrong.read("n", n, 0, 10); }),
              HasSubstr("expected an integer"));
  EXPECT_THAT(input_error_message([&] { wrong.read("flag", flag); }),
              HasSubstr("expected true or false"));
  EXPECT_THAT(input_error_message([&] { wrong.read_list("list", list, 3); }),
              HasSubstr("c.yaml: list has 2 values, expected 3"));
}

TEST(StrictMap, RejectsNonFiniteNumbersAndUnknownChoices) {
  StrictMap map(YAML::Load("{x: .nan, mode: warp}"), "d.yaml");
  double x = 0;
  std::string mode;
  EXPECT_THAT(input_error_message([&] { map.read("x", x, -1, 1); }), HasSubstr("expected finite"));
  EXPECT_THAT(input_error_message([&] {
                map.read("mode", mode, {"a", "b"});
              }),
              HasSubstr("d.yaml: mode = warp, expected one of a | b"));
}

TEST(LoadYamlFile, MissingAndMalformedFilesNameTheFile) {
  EXPECT_THAT(input_error_message([] { load_yaml_file("/nonexistent/onboard.yaml"); }),
              HasSubstr("/nonexistent/onboard.yaml: file not found"));
  const auto path = std::filesystem::temp_directory_path() / "hq_bad_yaml_test.yaml";
  std::ofstream(path) << "a: [1, 2\nb: 3\n";
  EXPECT_THAT(input_error_message([&] { load_yaml_file(path.string()); }),
              HasSubstr(path.string() + ":"));
  EXPECT_THAT(input_error_message([&] { load_yaml_file(path.string()); }),
              HasSubstr("not valid YAML"));
  std::filesystem::remove(path);
}

std::string write_file(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

// Each of these used to abort every loader with exit 134 (an uncaught yaml-cpp or iostream
// exception) or pass silently.
TEST(LoadYamlFile, DirectoryIsNamedNotACrash) {
  const auto dir = std::filesystem::temp_directory_path() / "hq_yaml_dir_test.yaml";
  std::filesystem::create_directories(dir);
  EXPECT_THAT(input_error_message([&] { load_yaml_file(dir.string()); }),
              HasSubstr(dir.string() + ": is a directory, expected a YAML file"));
  std::filesystem::remove(dir);
}

TEST(LoadYamlFile, ListOrMapKeyIsNamedWithFileLineAndPath) {
  const std::string list = write_file("hq_yaml_listkey.yaml", "odometry:\n  [a, b]: 1\n");
  EXPECT_THAT(
      input_error_message([&] { load_yaml_file(list); }),
      HasSubstr(list + ":2: odometry has key [a, b], which is a list, expected a scalar key"));
  const std::string map = write_file("hq_yaml_mapkey.yaml", "{a: 1}: 1\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(map); }),
              HasSubstr(map + ":1: top level has key {a: 1}, which is a mapping"));
  const std::string nested =
      write_file("hq_yaml_nestedkey.yaml", "boxes:\n  - {size_m: 1}\n  - {[x]: 2}\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(nested); }),
              HasSubstr("boxes[1] has key [x], which is a list"));
}

TEST(LoadYamlFile, DuplicateKeyNamesBothLinesAndTheValue) {
  const std::string path =
      write_file("hq_yaml_dup.yaml",
                 "odometry:\n  max_iterations_per_level: 10\n  max_iterations_per_level: 99\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(path); }),
              HasSubstr(path + ":3: odometry.max_iterations_per_level = 99 duplicates the key on "
                               "line 2, expected each key once"));
}

TEST(StrictMap, InMemoryMapsGetTheSameKeyChecks) {
  EXPECT_THAT(input_error_message([] { StrictMap(YAML::Load("{a: 1, a: 2}"), "m.yaml"); }),
              HasSubstr("m.yaml:1: a = 2 duplicates the key on line 1"));
  EXPECT_THAT(input_error_message([] { StrictMap(YAML::Load("{[1]: 1}"), "m.yaml"); }),
              HasSubstr("expected a scalar key"));
  EXPECT_THAT(input_error_message([] { StrictMap(YAML::Load("[1, 2]"), "m.yaml", "odometry"); }),
              HasSubstr("m.yaml: odometry = [1, 2], expected a mapping"));
}

TEST(StrictMap, MisspelledKeyNamesTheValueAndTheClosestKnownKey) {
  StrictMap map(YAML::Load("{gain: 1, gian: 2}"), "a.yaml");
  double gain = 0;
  map.read("gain", gain, 0, 10);
  EXPECT_THAT(input_error_message([&] { map.finish(); }),
              HasSubstr("a.yaml: gian is not a known key (value 2; did you mean gain?)"));
}

// GIVEN a shared file whose odometry section is misspelled, WHEN a loader reads only its own
// section, THEN the misspelling is rejected rather than the defaults used with exit 0, while
// another loader's section is accepted.
TEST(StrictMap, FinishSectionsRejectsAMisspelledSectionAndKeepsOthers) {
  StrictMap root(YAML::Load("{odometri: {max_iterations_per_level: 10}, obstacles: {gain: 1}}"),
                 "config/onboard.yaml");
  StrictMap odometry = root.child("odometry");
  odometry.finish();
  EXPECT_THAT(input_error_message([&] { root.finish_sections(); }),
              HasSubstr("config/onboard.yaml: odometri is not a known key (value "
                        "{max_iterations_per_level: 10}; did you mean odometry?)"));
  StrictMap fine(YAML::Load("{odometry: {}, obstacles: {gain: 1}, link: {}}"), "b.yaml");
  fine.child("odometry").finish();
  fine.finish_sections();
}

// The list of shared sections covers every section of the bundled onboard config.
TEST(StrictMap, SharedSectionsCoverTheBundledOnboardConfig) {
  const YAML::Node root = load_yaml_file("config/onboard.yaml");
  StrictMap map(root, "config/onboard.yaml");
  map.finish_sections();
}

// "Billion laughs": each level lists the previous one ten times, so 10 levels are 10^10 nodes
// once the aliases are expanded, in a file of a dozen lines.
std::string alias_bomb(int levels) {
  std::ostringstream text;
  text << "l0: &l0 lol\n";
  for (int level = 1; level <= levels; ++level) {
    text << "l" << level << ": &l" << level << " [";
    for (int i = 0; i < 10; ++i) text << (i > 0 ? ", " : "") << "*l" << level - 1;
    text << "]\n";
  }
  return text.str();
}

// GIVEN a 10-level alias bomb, WHEN loaded, THEN it is refused naming the file, the line of the
// entry that expands past the budget and the budget, instead of walking 10^10 nodes (every
// loader was busy for minutes).
TEST(LoadYamlFile, AliasBombIsRefusedNamingFileLineAndBudget) {
  const std::string path = write_file("hq_yaml_bomb.yaml", alias_bomb(10));
  const auto start = std::chrono::steady_clock::now();
  const std::string message = input_error_message([&] { load_yaml_file(path); });
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print("[ figures  ] 10-level alias bomb refused in {:.3f} s: {}\n", elapsed_s, message);
  EXPECT_THAT(message, HasSubstr(path + ":"));
  EXPECT_THAT(message, HasSubstr(std::to_string(kMaxYamlNodes)));
  EXPECT_LT(elapsed_s, 5.0) << "a generous bound that only catches a walk of the whole bomb";
}

// An alias may name the collection it sits in; a walk that follows it never ends.
TEST(LoadYamlFile, SelfReferenceIsRefusedNotWalkedForever) {
  const std::string path = write_file("hq_yaml_cycle.yaml", "a: &a [1, *a]\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(path); }), HasSubstr(path + ":"));
}

// An empty, comment-only or `~` file used to load as a mapping with no keys: every setting
// silently its default.
TEST(LoadYamlFile, EmptyCommentOnlyOrNullFileIsAnErrorNamingTheFile) {
  const std::string empty = write_file("hq_yaml_empty.yaml", "");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(empty); }),
              HasSubstr(empty + ": has no YAML document"));
  const std::string comments = write_file("hq_yaml_comments.yaml", "# odometry:\n#  gain: 2\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(comments); }),
              HasSubstr(comments + ": has no YAML document"));
  const std::string null = write_file("hq_yaml_null.yaml", "~\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(null); }),
              HasSubstr(null + ": top level is null, expected a YAML mapping"));
}

// yaml-cpp's Load reads the first document only: a second one was ignored without a word.
TEST(LoadYamlFile, SecondDocumentIsAnErrorNamingFileAndLine) {
  const std::string path = write_file("hq_yaml_two_docs.yaml",
                                      "odometry: {max_iterations_per_level: 10}\n---\n"
                                      "odometry: {max_iterations_per_level: 99}\n");
  EXPECT_THAT(input_error_message([&] { load_yaml_file(path); }),
              HasSubstr(path + ":3: a second YAML document, expected one"));
}

// `odometry:` with nothing under it, or `odometry: ~`, read as "all defaults"; a section that is
// meant to be defaults is left out.
TEST(LoadYamlFile, NullSectionIsAnErrorNamingFileAndSection) {
  for (const char* text : {"odometry:\nlink: {}\n", "odometry: ~\n"}) {
    const std::string path = write_file("hq_yaml_null_section.yaml", text);
    StrictMap root(load_yaml_file(path), path);
    EXPECT_THAT(input_error_message([&] { static_cast<void>(root.child("odometry")); }),
                HasSubstr(path + ":1: odometry is empty (null), expected a mapping"))
        << text;
  }
}

// Every YAML file the repository ships passes the loader's file-level checks (one document, a
// mapping, within the node budget, scalar keys once each).
TEST(LoadYamlFile, EveryShippedYamlFileLoads) {
  int loaded = 0;
  for (const char* folder : {"config", "calib", "onboard/sim/worlds", "onboard/sim/config",
                             "onboard/closed_loop/flights", "ground/config"}) {
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      if (entry.path().extension() != ".yaml") continue;
      EXPECT_NO_THROW(load_yaml_file(entry.path().string())) << entry.path();
      ++loaded;
    }
  }
  EXPECT_GE(loaded, 20);
}

}  // namespace
}  // namespace hq::config
