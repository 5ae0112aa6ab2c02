// Every tool that loads a YAML file, fed a directory, a key that is a list and a key given
// twice: exit status 2 with "<tool>: <file>..." naming what is wrong, never an abort (134) or
// a silent default. One case per loader and command-line flag.
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct Loader {
  std::string tool;               ///< Name printed before the message.
  std::vector<std::string> args;  ///< "{}" is replaced by the bad file.
};

std::vector<Loader> loaders() {
  const std::string sequence = "onboard/sim/worlds";  // any folder: the config fails first
  const std::string world = "onboard/sim/worlds/arena.yaml";
  const std::string script = "onboard/closed_loop/flights/core_paper_box.yaml";
  const auto sim_flight = [&](const std::string& flag) {
    std::vector<std::string> args = {HQ_SIM_FLIGHT_EXE};
    args.insert(args.end(), {"--world", flag == "--world" ? "{}" : world});
    args.insert(args.end(), {"--script", flag == "--script" ? "{}" : script});
    if (flag != "--world" && flag != "--script") args.insert(args.end(), {flag, "{}"});
    return Loader{"hq-sim-flight", args};
  };
  return {
      {"hq-odometry",
       {HQ_ODOMETRY_EXE, sequence, "--camera", "calib/tum_fr1.yaml", "--config", "{}"}},
      {"hq-odometry", {HQ_ODOMETRY_EXE, sequence, "--camera", "{}"}},
      sim_flight("--world"),
      sim_flight("--script"),
      sim_flight("--sim-config"),
      sim_flight("--config"),
      sim_flight("--vehicle"),
      {"hq-ground", {HQ_GROUND_EXE, "--device", "sim", "--headless", "--link-config", "{}"}},
      {"hq-ground", {HQ_GROUND_EXE, "--device", "sim", "--headless", "--haptics-config", "{}"}},
      {"hq-ground", {HQ_GROUND_EXE, "--device", "sim", "--headless", "--vehicle", "{}"}},
      {"hq-sim", {HQ_SIM_EXE, "--world", "{}", "--duration-s", "0.1"}},
  };
}

struct BadFile {
  std::string name;
  std::string text;  ///< Empty: a directory.
  std::string expected;
};

std::string run(const Loader& loader, const std::string& bad, const fs::path& out) {
  std::vector<std::string> args = loader.args;
  for (std::string& a : args) {
    if (a == "{}") a = bad;
  }
  int code = -1;
  {
    hq::testing::Process p(args, out.string());
    code = p.wait_exit(60.0);
  }
  std::ifstream in(out);
  std::stringstream ss;
  ss << in.rdbuf();
  return "exit " + std::to_string(code) + "\n" + ss.str();
}

TEST(ToolInputs, EveryLoaderExitsTwoNamingFileKeyAndValue) {
  const fs::path dir = fs::temp_directory_path() / ("hq_tool_inputs_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::vector<BadFile> files = {
      {"a_directory.yaml", "", ": is a directory, expected a YAML file"},
      {"list_key.yaml", "[a, b]: 1\n", ":1: top level has key [a, b], which is a list"},
      // yaml-cpp's bad conversion of a map to a key used to escape main: abort, status 134.
      {"map_key.yaml", "{a: 1}: 1\n",
       ":1: top level has key {a: 1}, which is a mapping, expected a scalar key"},
      {"duplicate.yaml", "name: one\nname: two\n",
       ":2: name = two duplicates the key on line 1, expected each key once"},
  };
  for (const BadFile& f : files) {
    const fs::path path = dir / f.name;
    if (f.text.empty()) {
      fs::create_directories(path);
    } else {
      std::ofstream(path) << f.text;
    }
    for (const Loader& loader : loaders()) {
      const std::string output = run(loader, path.string(), dir / "out.txt");
      std::string command;
      for (const std::string& a : loader.args) command += a + " ";
      SCOPED_TRACE(command + "<- " + f.name);
      EXPECT_THAT(output, HasSubstr("exit 2\n"));
      EXPECT_THAT(output, HasSubstr(loader.tool + ": " + path.string() + f.expected));
      EXPECT_THAT(output, Not(HasSubstr("terminate called")));
    }
  }
  fs::remove_all(dir);
}

// A misspelled section in a file whose one section a tool reads used to fall back to the
// defaults with exit 0.
TEST(ToolInputs, MisspelledSectionIsRejected) {
  const fs::path dir = fs::temp_directory_path() / ("hq_tool_sections_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path config = dir / "onboard.yaml";
  std::ofstream(config) << "odometri:\n  max_iterations_per_level: 10\n";
  const std::string output =
      run({"hq-odometry",
           {HQ_ODOMETRY_EXE, "onboard/sim/worlds", "--camera", "calib/tum_fr1.yaml", "--config",
            config.string(), "--out", (dir / "t.txt").string()}},
          config.string(), dir / "out.txt");
  EXPECT_THAT(output, HasSubstr("exit 2\n"));
  EXPECT_THAT(output, HasSubstr("hq-odometry: " + config.string() +
                                ": odometri is not a known key (value max_iterations_per_level: "
                                "10; did you mean odometry?)"));
  fs::remove_all(dir);
}

}  // namespace
