#include "hq/config/data_path.hpp"

#include "hq/config/strict_yaml.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <unistd.h>
#include <vector>

namespace hq::config {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// The tests run from the repository root; these move to an empty folder and back.
class DataPath : public ::testing::Test {
 protected:
  void SetUp() override {
    start_ = fs::current_path();
    empty_ = fs::temp_directory_path() / ("hq_data_path_" + std::to_string(::getpid()));
    fs::create_directories(empty_ / "config");
    fs::current_path(empty_);
  }
  void TearDown() override {
    fs::current_path(start_);
    ::unsetenv("HQ_DATA_DIRS");
    fs::remove_all(empty_);
  }
  fs::path start_;
  fs::path empty_;
};

TEST_F(DataPath, ShippedFilesAreFoundFromAnotherFolder) {
  const std::string resolved = resolve_data_path("config/onboard.yaml");
  EXPECT_NE(resolved, "config/onboard.yaml");
  EXPECT_TRUE(fs::exists(resolved)) << resolved;
  EXPECT_NO_THROW(load_yaml_file("config/onboard.yaml"));
}

TEST_F(DataPath, TheCurrentFolderWins) {
  std::ofstream(empty_ / "config" / "onboard.yaml") << "odometry: {}\n";
  EXPECT_EQ(resolve_data_path("config/onboard.yaml"), "config/onboard.yaml");
}

TEST_F(DataPath, DataDirsFromTheEnvironmentComeFirst) {
  const fs::path mine = empty_ / "mine";
  fs::create_directories(mine / "calib");
  std::ofstream(mine / "calib" / "tum_fr1.yaml") << "x: 1\n";
  ::setenv("HQ_DATA_DIRS", ("/nonexistent:" + mine.string()).c_str(), 1);
  EXPECT_EQ(resolve_data_path("calib/tum_fr1.yaml"), (mine / "calib" / "tum_fr1.yaml").string());
}

TEST_F(DataPath, AbsentFilesAreNamedWithEveryFolderTried) {
  EXPECT_EQ(resolve_data_path("config/absent.yaml"), "config/absent.yaml");
  const std::string message =
      hq::testing::input_error_message([] { load_yaml_file("config/absent.yaml"); });
  EXPECT_THAT(message, HasSubstr("config/absent.yaml: file not found"));
  EXPECT_THAT(message, HasSubstr("looked in the current folder"));
  EXPECT_THAT(message, HasSubstr("share/haptiquad"));
}

TEST_F(DataPath, InstalledProgramsNeverLookInTheSourceTree) {
  const std::vector<fs::path> dirs = data_dirs_for_executable("/opt/hq/bin/hq-onboard");
  ASSERT_EQ(dirs.size(), 1U);
  EXPECT_EQ(dirs[0], fs::path("/opt/hq/share/haptiquad"));
}

TEST_F(DataPath, ProgramsOfTheBuildTreeAlsoLookInTheSourceTree) {
  // This test runs from <build>/bin, like every program built here.
  const fs::path executable = fs::read_symlink("/proc/self/exe");
  const std::vector<fs::path> dirs = data_dirs_for_executable(executable);
  ASSERT_EQ(dirs.size(), 2U);
  EXPECT_TRUE(fs::exists(dirs[1] / "config" / "onboard.yaml")) << dirs[1];

  // A folder beside the build tree whose name merely starts with the build tree's is outside it.
  const fs::path build_dir = executable.parent_path().parent_path();
  const fs::path beside = fs::path(build_dir.string() + "-installed") / "bin" / "hq-onboard";
  EXPECT_EQ(data_dirs_for_executable(beside).size(), 1U);
}

TEST_F(DataPath, AbsolutePathsAreLeftAlone) {
  EXPECT_EQ(resolve_data_path("/nonexistent/onboard.yaml"), "/nonexistent/onboard.yaml");
}

}  // namespace
}  // namespace hq::config
