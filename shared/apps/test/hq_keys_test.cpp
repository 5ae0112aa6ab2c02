// hq-keys as a process: the layout it makes passes `hq-keys check`, the CA and identities get the
// validity asked for, and bad requests exit 2 with the reason.
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class HqKeys : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("hq_keys_app_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    keys_ = (dir_ / "keys").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs hq-keys with `args`; the exit code, output in output_.
  int run(std::vector<std::string> args) {
    args.insert(args.begin(), HQ_KEYS_EXE);
    const std::string out = (dir_ / "out.txt").string();
    int code = -1;
    {
      hq::testing::Process p(args, out);
      code = p.wait_exit(30.0);
    }
    std::ifstream in(out);
    std::stringstream ss;
    ss << in.rdbuf();
    output_ = ss.str();
    return code;
  }

  // Days from now to the certificate's notAfter.
  static double days_left(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "r");
    if (f == nullptr) return -1e9;
    X509* cert = PEM_read_X509(f, nullptr, nullptr, nullptr);
    std::fclose(f);
    if (cert == nullptr) return -1e9;
    int days = 0;
    int seconds = 0;
    ASN1_TIME_diff(&days, &seconds, nullptr, X509_get0_notAfter(cert));
    X509_free(cert);
    return days + seconds / 86'400.0;
  }

  fs::path dir_;
  std::string keys_;
  std::string output_;
};

TEST_F(HqKeys, MakesACheckedLayoutWithTheValidityAskedFor) {
  ASSERT_EQ(run({"init", keys_}), 0) << output_;
  ASSERT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "4"}), 0) << output_;
  ASSERT_EQ(run({"identity", keys_, "--role", "station", "--id", "2", "--vehicles", "4,5", "--days",
                 "30"}),
            0)
      << output_;
  EXPECT_THAT(output_, HasSubstr("CN=station_2,O=HaptiQuad"));
  EXPECT_EQ(run({"check", keys_, "--identity", "vehicle_4"}), 0) << output_;
  EXPECT_EQ(run({"check", keys_, "--identity", "station_2"}), 0) << output_;
  EXPECT_NEAR(days_left(keys_ + "/ca.pem"), 3650, 1);
  EXPECT_NEAR(days_left(keys_ + "/vehicle_4/cert.pem"), 365, 1);
  EXPECT_NEAR(days_left(keys_ + "/station_2/cert.pem"), 30, 1);
  std::ifstream permissions(keys_ + "/station_2/permissions.xml");
  std::stringstream xml;
  xml << permissions.rdbuf();
  EXPECT_THAT(xml.str(), HasSubstr("<partition>hq_vehicle_5</partition>"));
}

TEST_F(HqKeys, BadRequestsExitTwoWithTheReason) {
  ASSERT_EQ(run({"init", keys_}), 0) << output_;
  EXPECT_EQ(run({"init", keys_}), 2);
  EXPECT_THAT(output_, HasSubstr("a CA exists already"));
  EXPECT_EQ(run({"identity", keys_, "--role", "station", "--id", "1"}), 2);
  EXPECT_THAT(output_, HasSubstr("no vehicles to command"));
  EXPECT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "1", "--vehicles", "2"}), 2);
  EXPECT_THAT(output_, HasSubstr("--vehicles: only for --role station"));
  EXPECT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "1", "--domains", "7-300"}), 2);
  EXPECT_THAT(output_, HasSubstr("expected 0 <= min <= max <= 230"));
  EXPECT_EQ(run({"identity", (dir_ / "nowhere").string(), "--role", "vehicle", "--id", "1"}), 2);
  EXPECT_THAT(output_, HasSubstr("ca.pem: cannot read"));
  ASSERT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "1", "--start-days-ago", "10",
                 "--days", "1"}),
            0)
      << output_;
  EXPECT_EQ(run({"check", keys_, "--identity", "vehicle_1"}), 2);
  EXPECT_THAT(output_, HasSubstr(keys_ + "/vehicle_1/cert.pem: certificate expired"));
}

// GIVEN two complete keysets made by two `hq-keys init`, each identity passes `check` alone;
// WHEN checked against the other keyset's peer, THEN it exits 2 saying which CA each side has.
TEST_F(HqKeys, KeysetOfAnotherCaFailsTheCheckAgainstItsPeer) {
  const std::string vehicle_keys = (dir_ / "vehicle_keys").string();
  ASSERT_EQ(run({"init", keys_}), 0) << output_;
  ASSERT_EQ(run({"init", vehicle_keys}), 0) << output_;
  ASSERT_EQ(run({"identity", keys_, "--role", "station", "--id", "1", "--vehicles", "1"}), 0);
  ASSERT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "1"}), 0);
  ASSERT_EQ(run({"identity", vehicle_keys, "--role", "vehicle", "--id", "1"}), 0);
  EXPECT_EQ(run({"check", keys_, "--identity", "station_1"}), 0) << output_;
  EXPECT_EQ(run({"check", vehicle_keys, "--identity", "vehicle_1"}), 0) << output_;

  EXPECT_EQ(run({"check", keys_, "--identity", "station_1", "--peer", "vehicle_1"}), 0) << output_;
  EXPECT_THAT(output_, HasSubstr("station_1 and vehicle_1 can complete a handshake"));

  EXPECT_EQ(run({"check", keys_, "--identity", "station_1", "--peer", vehicle_keys + "/vehicle_1"}),
            2);
  EXPECT_THAT(output_,
              HasSubstr("a handshake between station_1 and vehicle_1 cannot succeed: "
                        "station_1's certificate " +
                        keys_ + "/station_1/cert.pem is signed by CA " + keys_ + "/ca.pem"));
  EXPECT_THAT(output_, HasSubstr("vehicle_1 trusts CA " + vehicle_keys + "/ca.pem"));

  EXPECT_EQ(run({"check", keys_, "--identity", "station_1", "--peer-ca", vehicle_keys + "/ca.pem"}),
            2);
  EXPECT_THAT(output_, HasSubstr("cannot succeed: station_1's certificate"));
}

// GIVEN an identity whose permissions.p7s is another identity's (signed by the same CA), WHEN
// checked, THEN it exits 2 naming both subjects.
TEST_F(HqKeys, PermissionsForAnotherSubjectFailTheCheck) {
  ASSERT_EQ(run({"init", keys_}), 0) << output_;
  ASSERT_EQ(run({"identity", keys_, "--role", "vehicle", "--id", "4"}), 0);
  ASSERT_EQ(run({"identity", keys_, "--role", "station", "--id", "2", "--vehicles", "4"}), 0);
  fs::copy_file(keys_ + "/station_2/permissions.p7s", keys_ + "/vehicle_4/permissions.p7s",
                fs::copy_options::overwrite_existing);
  EXPECT_EQ(run({"check", keys_, "--identity", "vehicle_4"}), 2);
  EXPECT_THAT(output_, HasSubstr(keys_ + "/vehicle_4/permissions.p7s: permissions document is "
                                         "for subject \"CN=station_2,O=HaptiQuad\""));
  EXPECT_THAT(output_, HasSubstr("\"CN=vehicle_4,O=HaptiQuad\""));
}

}  // namespace
