// hq-keys: DDS Security keys for the link (a CA, identities, signed governance and permissions).
//   hq-keys init DIR [--days 3650] [--domains 0-230]
//   hq-keys identity DIR --role vehicle --id 1 [--days 365]
//   hq-keys identity DIR --role station --id 1 --vehicles 1,2 [--days 365]
//   hq-keys check DIR --identity station_1 [--peer vehicle_1 | --peer OTHER_DIR/vehicle_1]
//                 [--peer-ca PEER_CA.pem]
// The layout and what the permissions allow: hq/security/keys.hpp.

#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/security/keys.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <ctime>
#include <optional>
#include <string>
#include <vector>

namespace {

hq::security::DomainRange parse_domains(const std::string& text) {
  hq::security::DomainRange range;
  const std::size_t dash = text.find('-');
  try {
    std::size_t used = 0;
    if (dash == std::string::npos) {
      range.min_id = range.max_id = std::stoi(text, &used);
      if (used != text.size()) throw std::invalid_argument(text);
    } else {
      range.min_id = std::stoi(text.substr(0, dash), &used);
      if (used != dash) throw std::invalid_argument(text);
      const std::string max = text.substr(dash + 1);
      range.max_id = std::stoi(max, &used);
      if (used != max.size()) throw std::invalid_argument(text);
    }
  } catch (const std::logic_error&) {
    throw hq::InputError("--domains " + text + ": expected ID or MIN-MAX (0..230)");
  }
  return range;
}

// --peer: "vehicle_1" in the keys directory checked, or "OTHER_DIR/vehicle_1" in another one.
hq::security::Peer peer_of(const std::string& dir, const std::string& peer) {
  const std::size_t slash = peer.find_last_of('/');
  if (slash == std::string::npos) return {peer, hq::security::files_in(dir, peer)};
  const std::string name = peer.substr(slash + 1);
  if (name.empty()) throw hq::InputError("--peer " + peer + ": expected [DIR/]IDENTITY");
  return {name, hq::security::files_in(peer.substr(0, slash), name)};
}

std::int64_t now_s() { return static_cast<std::int64_t>(std::time(nullptr)); }

// hq-keys check: the identity alone, then as each peer named would verify it.
void run_check(const std::string& dir, const std::string& identity, const std::string& peer,
               const std::string& peer_ca) {
  const hq::security::Peer own{identity, hq::security::files_in(dir, identity)};
  hq::security::check_identity(own.files, now_s());
  if (!peer.empty()) {
    const hq::security::Peer other = peer_of(dir, peer);
    hq::security::check_handshake(own, other, now_s());
    hq::log::info("hq-keys: {} and {} can complete a handshake\n", own.name.c_str(),
                  other.name.c_str());
  }
  if (!peer_ca.empty()) {
    hq::security::check_trusted_by(own, peer_ca, now_s());
    hq::log::info("hq-keys: a peer trusting {} accepts {}\n", peer_ca.c_str(), own.name.c_str());
  }
  hq::log::info("hq-keys: {}/{} ok\n", dir.c_str(), identity.c_str());
}

int run(int argc, char** argv) {
  CLI::App app{"hq-keys: DDS Security keys for the HaptiQuad link"};
  app.require_subcommand(1);
  std::string dir;
  // One variable per subcommand: CLI11 writes an option's default into its variable when the
  // option is declared, so a shared one would end up with the last subcommand's default.
  int ca_days = 3650;
  int identity_days = 365;
  std::string ca_domains = "0-230";
  std::string identity_domains = "0-230";

  CLI::App* init = app.add_subcommand("init", "make a CA and the signed governance document");
  init->add_option("DIR", dir, "keys directory (created)")->required();
  init->add_option("--days", ca_days, "CA validity in days")
      ->check(CLI::Range(1, 36500))
      ->capture_default_str();
  init->add_option("--domains", ca_domains, "DDS domain ids: ID or MIN-MAX")->capture_default_str();

  std::string role;
  std::uint32_t id = 1;
  std::vector<std::uint32_t> vehicles;
  int start_days_ago = 0;
  CLI::App* identity = app.add_subcommand(
      "identity", "make a key, a certificate signed by the CA and signed permissions");
  identity->add_option("DIR", dir, "keys directory made by `hq-keys init`")->required();
  identity->add_option("--role", role, "vehicle or station")
      ->required()
      ->check(CLI::IsMember({"vehicle", "station"}));
  identity->add_option("--id", id, "vehicle id or station id")->required();
  identity->add_option("--vehicles", vehicles, "vehicle ids a station may command (1,2,...)")
      ->delimiter(',');
  identity->add_option("--days", identity_days, "validity in days")
      ->check(CLI::Range(1, 36500))
      ->capture_default_str();
  identity
      ->add_option("--start-days-ago", start_days_ago,
                   "start the validity this many days ago (to test expired certificates)")
      ->check(CLI::Range(0, 36500));
  identity->add_option("--domains", identity_domains, "DDS domain ids: ID or MIN-MAX")
      ->capture_default_str();

  std::string identity_to_check;
  std::string peer;
  std::string peer_ca;
  CLI::App* check = app.add_subcommand("check", "check an identity's files as the link does");
  check->add_option("DIR", dir, "keys directory")->required();
  check->add_option("--identity", identity_to_check, "e.g. vehicle_1, station_2")->required();
  check->add_option("--peer", peer,
                    "the other end: an identity in DIR (vehicle_1) or in another keys "
                    "directory (OTHER_DIR/vehicle_1); checks that a handshake can succeed");
  check->add_option("--peer-ca", peer_ca,
                    "the CA certificate a peer trusts: checks that it accepts this identity");

  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  if (init->parsed()) {
    hq::security::make_ca(dir, hq::security::valid_for_days(now_s(), ca_days));
    hq::security::make_governance(dir, parse_domains(ca_domains));
    hq::log::info(
        "hq-keys: CA {}/ca.pem (key ca.key.pem: keep it off the vehicle), governance "
        "{}/governance.p7s\n",
        dir.c_str(), dir.c_str());
  } else if (identity->parsed()) {
    hq::security::IdentityRequest request;
    request.role = role == "vehicle" ? hq::security::Role::kVehicle : hq::security::Role::kStation;
    request.id = id;
    request.vehicles = vehicles;
    if (request.role == hq::security::Role::kVehicle && !vehicles.empty()) {
      throw hq::InputError("--vehicles: only for --role station (a vehicle is only itself)");
    }
    const std::int64_t start_s = now_s() - std::int64_t{start_days_ago} * 86'400;
    request.validity = hq::security::valid_for_days(start_s, identity_days);
    request.domains = parse_domains(identity_domains);
    hq::security::make_identity(dir, request);
    const std::string name = hq::security::identity_name(request.role, id);
    hq::log::info("hq-keys: identity {}/{} ({})\n", dir.c_str(), name.c_str(),
                  hq::security::subject_name(request.role, id).c_str());
  } else if (check->parsed()) {
    run_check(dir, identity_to_check, peer, peer_ca);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-keys", argc, argv, run); }
