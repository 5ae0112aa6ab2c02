// hq::security: keys and documents made here verify with OpenSSL, and check_identity names the
// file and the problem for every way an identity can be broken.
#include "hq/security/keys.hpp"

#include "hq/testing/input_error.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <sstream>
#include <string>
#include <unistd.h>

namespace hq::security {
namespace {

std::int64_t now_s() { return static_cast<std::int64_t>(std::time(nullptr)); }

class Keys : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (std::filesystem::temp_directory_path() /
            ("hq_keys_test_" + std::to_string(getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name()))
               .string();
    std::filesystem::remove_all(dir_);
    make_ca(dir_, valid_for_days(now_s(), 30));
    make_governance(dir_, DomainRange{});
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  IdentityFiles vehicle(std::int64_t not_before_s, std::int64_t not_after_s) {
    IdentityRequest request;
    request.role = Role::kVehicle;
    request.id = 3;
    request.validity = {not_before_s, not_after_s};
    make_identity(dir_, request);
    return files_in(dir_, "vehicle_3");
  }

  std::string dir_;
};

TEST_F(Keys, FreshIdentityPassesTheChecks) {
  const IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  EXPECT_NO_THROW(check_identity(files, now_s()));
  EXPECT_EQ(files.certificate, dir_ + "/vehicle_3/cert.pem");
}

TEST_F(Keys, PermissionsGrantOnlyTheVehiclesOwnPartitionAndTopics) {
  IdentityRequest station;
  station.role = Role::kStation;
  station.id = 2;
  station.vehicles = {1, 4};
  station.validity = valid_for_days(now_s(), 1);
  const std::string xml = permissions_xml(station);
  EXPECT_NE(xml.find("<subject_name>CN=station_2,O=HaptiQuad</subject_name>"), std::string::npos);
  EXPECT_NE(xml.find("<partition>hq_vehicle_1</partition>"), std::string::npos);
  EXPECT_NE(xml.find("<partition>hq_vehicle_4</partition>"), std::string::npos);
  EXPECT_EQ(xml.find("<partition>hq_vehicle_2</partition>"), std::string::npos);
  // A station publishes commands and never vehicle state.
  const std::size_t publish = xml.find("<publish>");
  const std::size_t subscribe = xml.find("<subscribe>");
  ASSERT_NE(publish, std::string::npos);
  ASSERT_NE(subscribe, std::string::npos);
  const std::string published = xml.substr(publish, subscribe - publish);
  EXPECT_NE(published.find("hq_velocity_command"), std::string::npos);
  EXPECT_EQ(published.find("hq_vehicle_state"), std::string::npos);
  // It reads what its vehicles send, and the commands they receive (its flight record).
  const std::string subscribed = xml.substr(subscribe, xml.find("</subscribe>") - subscribe);
  EXPECT_NE(subscribed.find("hq_vehicle_state"), std::string::npos);
  EXPECT_NE(subscribed.find("hq_velocity_command"), std::string::npos);
  EXPECT_NE(xml.find("<default>DENY</default>"), std::string::npos);
  // Its own station partitions, to publish in only: the certificate behind what it writes.
  EXPECT_NE(published.find("<partition>hq_vehicle_1_station_2</partition>"), std::string::npos);
  EXPECT_NE(published.find("<partition>hq_vehicle_4_station_2</partition>"), std::string::npos);
  EXPECT_EQ(subscribed.find("_station_"), std::string::npos);
  EXPECT_EQ(xml.find("<partition>hq_vehicle_1_station_1</partition>"), std::string::npos);

  station.vehicles.clear();
  EXPECT_NE(testing::input_error_message([&] { permissions_xml(station); }).find("no vehicles"),
            std::string::npos);
}

TEST_F(Keys, AVehicleReadsItsOwnTopicsForItsFlightLogButWritesNoCommand) {
  IdentityRequest request;
  request.role = Role::kVehicle;
  request.id = 3;
  request.validity = valid_for_days(now_s(), 1);
  const std::string xml = permissions_xml(request);
  const std::size_t publish = xml.find("<publish>");
  const std::size_t subscribe = xml.find("<subscribe>");
  ASSERT_NE(publish, std::string::npos);
  ASSERT_NE(subscribe, std::string::npos);
  const std::string published = xml.substr(publish, subscribe - publish);
  EXPECT_NE(published.find("hq_vehicle_state"), std::string::npos);
  EXPECT_EQ(published.find("hq_velocity_command"), std::string::npos);
  const std::string subscribed = xml.substr(subscribe, xml.find("</subscribe>") - subscribe);
  for (const char* topic : {"hq_vehicle_state", "hq_camera_frame", "hq_event", "hq_heartbeat",
                            "hq_velocity_command", "hq_mode_request"}) {
    EXPECT_NE(subscribed.find(topic), std::string::npos) << topic;
  }
  EXPECT_NE(xml.find("<partition>hq_vehicle_3</partition>"), std::string::npos);
  EXPECT_EQ(xml.find("_station_"), std::string::npos);  // a vehicle speaks for no station
}

TEST_F(Keys, StationPartitionsNameTheirStationAndNothingElseParses) {
  EXPECT_EQ(station_partition(1, 3), "hq_vehicle_1_station_3");
  EXPECT_EQ(station_of_partition(station_partition(1, 3), 1), 3U);
  EXPECT_EQ(station_of_partition(station_partition(12, 4000000000U), 12), 4000000000U);
  EXPECT_EQ(station_of_partition(station_partition(2, 3), 1), 0U);  // another vehicle's
  EXPECT_EQ(station_of_partition(station_partition(1, 3), 11), 0U);
  for (const char* not_one : {"hq_vehicle_1", "hq_vehicle_1_station_", "hq_vehicle_1_station_03",
                              "hq_vehicle_1_station_3x", "hq_vehicle_1_station_-3",
                              "hq_vehicle_1_station_99999999999", "", "hq_vehicle_1_station_*"}) {
    EXPECT_EQ(station_of_partition(not_one, 1), 0U) << not_one;
  }
}

TEST_F(Keys, GovernanceEncryptsEveryLinkTopic) {
  const std::string xml = governance_xml(DomainRange{});
  EXPECT_NE(xml.find("<topic_expression>hq_*</topic_expression>"), std::string::npos);
  EXPECT_NE(xml.find("<data_protection_kind>ENCRYPT</data_protection_kind>"), std::string::npos);
  EXPECT_NE(xml.find("<allow_unauthenticated_participants>false"), std::string::npos);
  EXPECT_NE(xml.find("<enable_join_access_control>true"), std::string::npos);
  EXPECT_NE(testing::input_error_message([] {
              governance_xml(DomainRange{5, 231});
            }).find("expected 0 <= min <= max <= 230"),
            std::string::npos);
}

TEST_F(Keys, MissingFileIsNamed) {
  IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  std::filesystem::remove(files.private_key);
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.private_key), std::string::npos) << message;
  EXPECT_NE(message.find("private key missing"), std::string::npos) << message;
}

TEST_F(Keys, ExpiredCertificateIsNamed) {
  const IdentityFiles files = vehicle(now_s() - 10 * 86'400, now_s() - 86'400);
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.certificate), std::string::npos) << message;
  EXPECT_NE(message.find("expired"), std::string::npos) << message;
}

TEST_F(Keys, CertificateNotYetValidIsNamed) {
  const IdentityFiles files = vehicle(now_s() + 86'400, now_s() + 2 * 86'400);
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find("not valid yet"), std::string::npos) << message;
}

TEST_F(Keys, CertificateOfAnotherCaIsNamed) {
  IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  const std::string other = dir_ + "/other";
  make_ca(other, valid_for_days(now_s(), 30));
  files.identity_ca = other + "/ca.pem";
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.certificate), std::string::npos) << message;
  EXPECT_NE(message.find("not signed by the identity CA"), std::string::npos) << message;
}

TEST_F(Keys, KeyOfAnotherIdentityIsNamed) {
  IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  IdentityRequest station;
  station.role = Role::kStation;
  station.id = 1;
  station.vehicles = {3};
  station.validity = valid_for_days(now_s(), 1);
  make_identity(dir_, station);
  files.private_key = files_in(dir_, "station_1").private_key;
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.private_key), std::string::npos) << message;
  EXPECT_NE(message.find("does not match the certificate"), std::string::npos) << message;
}

TEST_F(Keys, TamperedPermissionsDoNotVerify) {
  const IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  std::ifstream in(files.permissions);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t at = text.find("hq_vehicle_3");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 12, "hq_vehicle_4");  // grant itself another vehicle's partition
  std::ofstream(files.permissions) << text;
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.permissions), std::string::npos) << message;
  EXPECT_NE(message.find("signature does not verify"), std::string::npos) << message;
}

// `xml` signed by the CA in `dir` as hq-keys signs permissions (detached S/MIME, text).
void sign_as_ca(const std::string& dir, const std::string& xml, const std::string& out_path) {
  std::FILE* f = std::fopen((dir + "/ca.pem").c_str(), "r");
  ASSERT_NE(f, nullptr);
  X509* ca = PEM_read_X509(f, nullptr, nullptr, nullptr);
  std::fclose(f);
  f = std::fopen((dir + "/ca.key.pem").c_str(), "r");
  ASSERT_NE(f, nullptr);
  EVP_PKEY* key = PEM_read_PrivateKey(f, nullptr, nullptr, nullptr);
  std::fclose(f);
  ASSERT_NE(ca, nullptr);
  ASSERT_NE(key, nullptr);
  const int flags = PKCS7_DETACHED | PKCS7_TEXT | PKCS7_STREAM;
  BIO* in = BIO_new_mem_buf(xml.data(), static_cast<int>(xml.size()));
  PKCS7* p7 = PKCS7_sign(ca, key, nullptr, in, flags);
  BIO* out = BIO_new_file(out_path.c_str(), "w");
  EXPECT_EQ(SMIME_write_PKCS7(out, p7, in, flags), 1);
  BIO_free(out);
  PKCS7_free(p7);
  BIO_free(in);
  EVP_PKEY_free(key);
  X509_free(ca);
}

IdentityRequest station_for_vehicle_3() {
  IdentityRequest station;
  station.role = Role::kStation;
  station.id = 1;
  station.vehicles = {3};
  station.validity = valid_for_days(now_s(), 1);
  return station;
}

// Cyclone's access control refuses a participant whose permissions grant another subject;
// the signature alone verifies, so only the subject tells.
TEST_F(Keys, PermissionsForAnotherSubjectAreRefusedNamingBoth) {
  IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  make_identity(dir_, station_for_vehicle_3());
  files.permissions = files_in(dir_, "station_1").permissions;
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.permissions), std::string::npos) << message;
  EXPECT_NE(message.find("permissions document is for subject \"CN=station_1,O=HaptiQuad\""),
            std::string::npos)
      << message;
  EXPECT_NE(message.find(files.certificate + "'s subject \"CN=vehicle_3,O=HaptiQuad\""),
            std::string::npos)
      << message;
}

// A station's permissions made before identities were bound to certificates grant no station
// partition: every writer of it would be refused at run time. The check says so up front.
TEST_F(Keys, StationPermissionsWithoutItsStationPartitionAreRefusedSayingWhy) {
  make_identity(dir_, station_for_vehicle_3());
  const IdentityFiles files = files_in(dir_, "station_1");
  EXPECT_NO_THROW(check_identity(files, now_s()));
  std::string old_grant = permissions_xml(station_for_vehicle_3());
  const std::string own = "            <partition>hq_vehicle_3_station_1</partition>\n";
  ASSERT_NE(old_grant.find(own), std::string::npos);
  old_grant.erase(old_grant.find(own), own.size());
  sign_as_ca(dir_, old_grant, files.permissions);
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find(files.permissions), std::string::npos) << message;
  EXPECT_NE(message.find("not its station partition hq_vehicle_3_station_1"), std::string::npos)
      << message;
  EXPECT_NE(message.find("hq-keys identity KEYS --role station --id 1"), std::string::npos)
      << message;
}

// Cyclone compares the attributes in any order, but as written: a subject equal as an X.509
// name yet written with spaces or long names is refused by it, so by the check too.
TEST_F(Keys, SubjectInAnotherOrderPassesOneWrittenOtherwiseIsRefusedAsCycloneDoes) {
  const IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  IdentityRequest request;
  request.role = Role::kVehicle;
  request.id = 3;
  request.validity = valid_for_days(now_s(), 1);
  const std::string xml = permissions_xml(request);
  const std::string subject = "CN=vehicle_3,O=HaptiQuad";
  const auto signed_with_subject = [&](const std::string& written) {
    std::string text = xml;
    text.replace(text.find(subject), subject.size(), written);
    sign_as_ca(dir_, text, files.permissions);
  };
  signed_with_subject("O=HaptiQuad,CN=vehicle_3");
  EXPECT_NO_THROW(check_identity(files, now_s()));
  signed_with_subject("O=HaptiQuad, commonName=vehicle_3");
  const std::string message = testing::input_error_message([&] { check_identity(files, now_s()); });
  EXPECT_NE(message.find("permissions subject \"O=HaptiQuad, commonName=vehicle_3\" is the "
                         "certificate " +
                         files.certificate + "'s subject as an X.509 name"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("write \"CN=vehicle_3,O=HaptiQuad\""), std::string::npos) << message;
}

TEST_F(Keys, PeersOfOneCaCanHandshake) {
  const IdentityFiles vehicle_files = vehicle(now_s() - 60, now_s() + 86'400);
  make_identity(dir_, station_for_vehicle_3());
  EXPECT_NO_THROW(check_handshake({"station_1", files_in(dir_, "station_1")},
                                  {"vehicle_3", vehicle_files}, now_s()));
  EXPECT_NO_THROW(check_trusted_by({"vehicle_3", vehicle_files}, dir_ + "/ca.pem", now_s()));
}

// A complete keyset of another CA passes check_identity alone; only the peer's view tells.
TEST_F(Keys, KeysetOfAnotherCaCannotHandshakeAndSaysWhichCaEachTrusts) {
  const IdentityFiles vehicle_files = vehicle(now_s() - 60, now_s() + 86'400);
  const std::string other = dir_ + "/other";
  make_ca(other, valid_for_days(now_s(), 30));
  make_governance(other, DomainRange{});
  make_identity(other, station_for_vehicle_3());
  const IdentityFiles station_files = files_in(other, "station_1");
  ASSERT_NO_THROW(check_identity(station_files, now_s()));
  const std::string message = testing::input_error_message([&] {
    check_handshake({"station_1", station_files}, {"vehicle_3", vehicle_files}, now_s());
  });
  EXPECT_NE(message.find("a handshake between station_1 and vehicle_3 cannot succeed: "
                         "station_1's certificate " +
                         station_files.certificate + " is signed by CA " + other + "/ca.pem"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("vehicle_3 trusts CA " + dir_ + "/ca.pem"), std::string::npos) << message;
  EXPECT_NE(message.find("vehicle_3's certificate"), std::string::npos) << message;
  EXPECT_NE(message.find("station_1's permissions"), std::string::npos) << message;
  EXPECT_NE(message.find("SHA-256 "), std::string::npos) << message;

  const std::string one_way = testing::input_error_message([&] {
    check_trusted_by({"station_1", station_files}, dir_ + "/ca.pem", now_s());
  });
  EXPECT_NE(one_way.find("station_1's certificate " + station_files.certificate +
                         " is signed by CA " + other + "/ca.pem"),
            std::string::npos)
      << one_way;
}

TEST_F(Keys, ExistingCaIsNotOverwritten) {
  const std::string message =
      testing::input_error_message([&] { make_ca(dir_, valid_for_days(now_s(), 1)); });
  EXPECT_NE(message.find("a CA exists already"), std::string::npos) << message;
}

TEST_F(Keys, PrivateKeysAreOwnerOnly) {
  const IdentityFiles files = vehicle(now_s() - 60, now_s() + 86'400);
  const auto perms = std::filesystem::status(files.private_key).permissions();
  EXPECT_EQ(perms & (std::filesystem::perms::group_all | std::filesystem::perms::others_all),
            std::filesystem::perms::none);
}

}  // namespace
}  // namespace hq::security
