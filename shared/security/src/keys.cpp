#include "hq/security/keys.hpp"

#include "hq/base/error.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <iterator>
#include <memory>
#include <openssl/bio.h>
#include <openssl/bn.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <optional>
#include <sstream>
#include <string_view>
#include <sys/stat.h>
#include <unistd.h>
#include <utility>
#include <vector>

namespace hq::security {

namespace {

// RAII for the OpenSSL objects used here.
struct Free {
  void operator()(BIO* p) const { BIO_free_all(p); }
  void operator()(EVP_PKEY* p) const { EVP_PKEY_free(p); }
  void operator()(X509* p) const { X509_free(p); }
  void operator()(X509_STORE* p) const { X509_STORE_free(p); }
  void operator()(PKCS7* p) const { PKCS7_free(p); }
  void operator()(BIGNUM* p) const { BN_free(p); }
};
template <typename T>
using Owned = std::unique_ptr<T, Free>;

// The OpenSSL error queue as text (emptied), for messages.
std::string openssl_reason() {
  std::string reason;
  while (const unsigned long code = ERR_get_error()) {
    char text[256];
    ERR_error_string_n(code, text, sizeof text);
    reason += (reason.empty() ? "" : "; ") + std::string(text);
  }
  return reason.empty() ? "unknown OpenSSL error" : reason;
}

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw InputError(where + ": " + what);
}

void require(bool ok, const std::string& where, const std::string& what) {
  if (!ok) fail(where, what + " (" + openssl_reason() + ")");
}

const char* role_word(Role role) { return role == Role::kVehicle ? "vehicle" : "station"; }

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot read: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Writes atomically enough for keys: a private key is created 0600 before any byte is written.
void write_file(const std::string& path, const std::string& text, bool secret = false) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) fail(path, std::string("cannot write: ") + std::strerror(errno));
  if (secret) ::fchmod(fileno(f), S_IRUSR | S_IWUSR);
  const bool written = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed || std::rename(tmp.c_str(), path.c_str()) != 0) {
    fail(path, std::string("cannot write: ") + std::strerror(errno));
  }
}

std::string bio_text(BIO* bio) {
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio, &data);
  return std::string(data, static_cast<std::size_t>(n));
}

Owned<BIO> memory_bio() {
  Owned<BIO> bio(BIO_new(BIO_s_mem()));
  require(bio != nullptr, "BIO_new", "out of memory");
  return bio;
}

Owned<EVP_PKEY> make_key() {
  Owned<EVP_PKEY> key(EVP_EC_gen("P-256"));
  require(key != nullptr, "EVP_EC_gen(P-256)", "key generation failed");
  return key;
}

std::string key_pem(EVP_PKEY* key) {
  Owned<BIO> bio = memory_bio();
  require(PEM_write_bio_PrivateKey(bio.get(), key, nullptr, nullptr, 0, nullptr, nullptr) == 1,
          "PEM_write_bio_PrivateKey", "failed");
  return bio_text(bio.get());
}

std::string cert_pem(X509* cert) {
  Owned<BIO> bio = memory_bio();
  require(PEM_write_bio_X509(bio.get(), cert) == 1, "PEM_write_bio_X509", "failed");
  return bio_text(bio.get());
}

Owned<X509> load_cert(const std::string& path) {
  const std::string text = read_file(path);
  Owned<BIO> bio(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  Owned<X509> cert(PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr));
  if (cert == nullptr) fail(path, "not a PEM certificate (" + openssl_reason() + ")");
  return cert;
}

Owned<EVP_PKEY> load_key(const std::string& path) {
  const std::string text = read_file(path);
  Owned<BIO> bio(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  Owned<EVP_PKEY> key(PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr));
  if (key == nullptr) {
    fail(path, "not an unencrypted PEM private key (" + openssl_reason() + ")");
  }
  return key;
}

void add_name_entry(X509_NAME* name, const char* field, const std::string& value) {
  require(X509_NAME_add_entry_by_txt(name, field, MBSTRING_UTF8,
                                     reinterpret_cast<const unsigned char*>(value.c_str()), -1, -1,
                                     0) == 1,
          "X509_NAME_add_entry_by_txt", field);
}

void add_extension(X509* cert, X509* issuer, int nid, const char* value) {
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, issuer, cert, nullptr, nullptr, 0);
  X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &ctx, nid, value);
  require(ext != nullptr, "X509V3_EXT_conf_nid", value);
  const int ok = X509_add_ext(cert, ext, -1);
  X509_EXTENSION_free(ext);
  require(ok == 1, "X509_add_ext", value);
}

// A certificate for `key` with subject CN=`common_name`,O=HaptiQuad, signed by issuer_key
// (self-signed when issuer is null).
Owned<X509> make_cert(EVP_PKEY* key, const std::string& common_name, const Validity& validity,
                      X509* issuer, EVP_PKEY* issuer_key) {
  Owned<X509> cert(X509_new());
  require(cert != nullptr, "X509_new", "out of memory");
  X509_set_version(cert.get(), 2);  // v3, for the extensions
  // 64 random bits of serial: two certificates of one CA never share a serial.
  Owned<BIGNUM> serial(BN_new());
  require(serial != nullptr && BN_rand(serial.get(), 63, BN_RAND_TOP_ANY, BN_RAND_BOTTOM_ANY) == 1,
          "BN_rand", "serial");
  require(BN_to_ASN1_INTEGER(serial.get(), X509_get_serialNumber(cert.get())) != nullptr,
          "BN_to_ASN1_INTEGER", "serial");
  require(ASN1_TIME_set(X509_getm_notBefore(cert.get()),
                        static_cast<time_t>(validity.not_before_s)) != nullptr,
          "ASN1_TIME_set", "notBefore");
  require(ASN1_TIME_set(X509_getm_notAfter(cert.get()),
                        static_cast<time_t>(validity.not_after_s)) != nullptr,
          "ASN1_TIME_set", "notAfter");
  X509_NAME* subject = X509_get_subject_name(cert.get());
  add_name_entry(subject, "CN", common_name);
  add_name_entry(subject, "O", "HaptiQuad");
  require(X509_set_pubkey(cert.get(), key) == 1, "X509_set_pubkey", "failed");
  X509* signer = issuer != nullptr ? issuer : cert.get();
  require(X509_set_issuer_name(cert.get(), X509_get_subject_name(signer)) == 1,
          "X509_set_issuer_name", "failed");
  if (issuer == nullptr) {
    add_extension(cert.get(), signer, NID_basic_constraints, "critical,CA:TRUE");
    add_extension(cert.get(), signer, NID_key_usage,
                  "critical,keyCertSign,cRLSign,digitalSignature");
  } else {
    add_extension(cert.get(), signer, NID_basic_constraints, "critical,CA:FALSE");
    add_extension(cert.get(), signer, NID_key_usage, "critical,digitalSignature,keyAgreement");
  }
  add_extension(cert.get(), signer, NID_subject_key_identifier, "hash");
  require(X509_sign(cert.get(), issuer_key != nullptr ? issuer_key : key, EVP_sha256()) > 0,
          "X509_sign", common_name);
  return cert;
}

// `document` signed by the CA as `openssl smime -sign -text` does: detached, text/plain header
// inside the signed part, multipart/signed S/MIME output (what Cyclone's access control reads).
std::string smime_sign(const std::string& document, X509* ca, EVP_PKEY* ca_key) {
  const int flags = PKCS7_DETACHED | PKCS7_TEXT | PKCS7_STREAM;
  Owned<BIO> in(BIO_new_mem_buf(document.data(), static_cast<int>(document.size())));
  Owned<PKCS7> p7(PKCS7_sign(ca, ca_key, nullptr, in.get(), flags));
  require(p7 != nullptr, "PKCS7_sign", "signing failed");
  Owned<BIO> out = memory_bio();
  require(SMIME_write_PKCS7(out.get(), p7.get(), in.get(), flags) == 1, "SMIME_write_PKCS7",
          "failed");
  return bio_text(out.get());
}

std::string iso_utc(std::int64_t t_s) {
  const std::time_t t = static_cast<std::time_t>(t_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%S", &tm);
  return text;
}

std::string domains_xml(const DomainRange& domains, const char* indent) {
  std::ostringstream xml;
  xml << indent << "<domains>\n"
      << indent << "  <id_range><min>" << domains.min_id << "</min><max>" << domains.max_id
      << "</max></id_range>\n"
      << indent << "</domains>\n";
  return xml.str();
}

void check_domains(const DomainRange& domains) {
  if (domains.min_id < 0 || domains.max_id > kMaxSecuredDomainId ||
      domains.min_id > domains.max_id) {
    throw InputError("domains " + std::to_string(domains.min_id) + "-" +
                     std::to_string(domains.max_id) +
                     ": expected 0 <= min <= max <= " + std::to_string(kMaxSecuredDomainId) +
                     " (the largest id Cyclone's access control accepts)");
  }
}

struct Ca {
  Owned<X509> cert;
  Owned<EVP_PKEY> key;
};

Ca load_ca(const std::string& dir) {
  const IdentityFiles files = files_in(dir, "");
  return {load_cert(files.identity_ca), load_key(dir + "/ca.key.pem")};
}

void make_dir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) fail(dir, "cannot create directory: " + ec.message());
}

void check_readable(const std::string& path, const char* what) {
  if (path.empty()) throw InputError(std::string("security: no ") + what + " file configured");
  if (::access(path.c_str(), F_OK) != 0) {
    fail(path, std::string(what) + " missing (make keys with `hq-keys`)");
  }
  if (::access(path.c_str(), R_OK) != 0) {
    fail(path, std::string(what) + " not readable: " + std::strerror(errno));
  }
}

std::string asn1_time_text(const ASN1_TIME* t) {
  Owned<BIO> bio = memory_bio();
  ASN1_TIME_print(bio.get(), t);
  return bio_text(bio.get());
}

void check_times(X509* cert, const std::string& path, const char* what, std::int64_t now_s) {
  time_t now = static_cast<time_t>(now_s);
  if (X509_cmp_time(X509_get0_notAfter(cert), &now) < 0) {
    fail(path, std::string(what) + " expired (not after " +
                   asn1_time_text(X509_get0_notAfter(cert)) + "); make a new one with `hq-keys`");
  }
  if (X509_cmp_time(X509_get0_notBefore(cert), &now) > 0) {
    fail(path, std::string(what) + " not valid yet (not before " +
                   asn1_time_text(X509_get0_notBefore(cert)) + "); check this machine's clock");
  }
}

// The content of an S/MIME signed document if its signature verifies against `ca` (and nothing
// else); nullopt with the reason in `why` otherwise.
std::optional<std::string> verified_content(const std::string& path, const char* what, X509* ca,
                                            const std::string& ca_path, std::string& why) {
  const std::string text = read_file(path);
  Owned<BIO> in(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  BIO* content_raw = nullptr;
  Owned<PKCS7> p7(SMIME_read_PKCS7(in.get(), &content_raw));
  Owned<BIO> content(content_raw);
  if (p7 == nullptr) fail(path, std::string(what) + " is not an S/MIME signed document");
  Owned<X509_STORE> store(X509_STORE_new());
  require(store != nullptr && X509_STORE_add_cert(store.get(), ca) == 1, "X509_STORE_add_cert",
          ca_path);
  Owned<BIO> out = memory_bio();
  if (PKCS7_verify(p7.get(), nullptr, store.get(), content.get(), out.get(), PKCS7_TEXT) != 1) {
    why = openssl_reason();
    return std::nullopt;
  }
  return bio_text(out.get());
}

std::string check_signed(const std::string& path, const char* what, X509* ca,
                         const std::string& ca_path) {
  std::string why;
  std::optional<std::string> content = verified_content(path, what, ca, ca_path, why);
  if (!content) {
    fail(path,
         std::string(what) + " signature does not verify against " + ca_path + " (" + why + ")");
  }
  return *std::move(content);
}

// An X.509 name as (short attribute name, UTF-8 value) pairs in its order.
using NameParts = std::vector<std::pair<std::string, std::string>>;

NameParts name_parts(const X509_NAME* name) {
  NameParts parts;
  for (int i = 0; i < X509_NAME_entry_count(name); ++i) {
    const X509_NAME_ENTRY* entry = X509_NAME_get_entry(name, i);
    const int nid = OBJ_obj2nid(X509_NAME_ENTRY_get_object(entry));
    unsigned char* utf8 = nullptr;
    const int n = ASN1_STRING_to_UTF8(&utf8, X509_NAME_ENTRY_get_data(entry));
    const std::string value =
        n >= 0 ? std::string(reinterpret_cast<char*>(utf8), static_cast<std::size_t>(n)) : "";
    OPENSSL_free(utf8);
    parts.emplace_back(nid == NID_undef ? "?" : OBJ_nid2sn(nid), value);
  }
  return parts;
}

std::string trimmed(const std::string& text) {
  const std::size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(" \t\r\n") - first + 1);
}

// A subject_name of a permissions grant ("CN=vehicle_1,O=HaptiQuad", RFC 4514 as the DDS
// Security spec writes it) as name parts, attribute names as OpenSSL's short names so that
// "commonName=" and "CN=" compare equal; backslash escapes are undone.
NameParts name_parts(const std::string& text) {
  NameParts parts;
  std::string part;
  const auto add = [&] {
    const std::size_t eq = part.find('=');
    const std::string key = trimmed(part.substr(0, eq));
    const int nid = OBJ_txt2nid(key.c_str());
    parts.emplace_back(nid == NID_undef ? key : OBJ_nid2sn(nid),
                       eq == std::string::npos ? "" : trimmed(part.substr(eq + 1)));
    part.clear();
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\\' && i + 1 < text.size()) {
      part += text[++i];
    } else if (text[i] == ',') {
      add();
    } else {
      part += text[i];
    }
  }
  add();
  return parts;
}

std::string name_text(const NameParts& parts) {
  std::string text;
  for (const auto& [key, value] : parts) text += (text.empty() ? "" : ",") + key + "=" + value;
  return text;
}

// Whether two names hold the same attributes, in any order: equal as X.509 names.
bool same_name(NameParts a, NameParts b) {
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b;
}

// Whether a grant's subject_name covers `subject` as Cyclone's access control decides it
// (ac_check_subjects_are_equal): the text split at ',', '/' or '|' and at the first '=', every
// attribute of the certificate's subject found by its short name, as written, with the same
// value; order free, but no space trimmed and no long attribute name understood.
bool cyclone_grants(const std::string& text, const NameParts& subject) {
  NameParts granted;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find_first_of(",/|", start), text.size());
    const std::string token = text.substr(start, end - start);
    const std::size_t eq = token.find('=');
    if (!token.empty() && eq != std::string::npos) {
      granted.emplace_back(token.substr(0, eq), token.substr(eq + 1));
    }
    start = end + 1;
  }
  return std::all_of(subject.begin(), subject.end(), [&](const auto& part) {
    return std::find(granted.begin(), granted.end(), part) != granted.end();
  });
}

// Every <subject_name> of the grants in a permissions document.
std::vector<std::string> permission_subjects(const std::string& xml) {
  static constexpr std::string_view kOpen = "<subject_name>";
  static constexpr std::string_view kClose = "</subject_name>";
  std::vector<std::string> subjects;
  for (std::size_t at = xml.find(kOpen); at != std::string::npos; at = xml.find(kOpen, at)) {
    at += kOpen.size();
    const std::size_t end = xml.find(kClose, at);
    if (end == std::string::npos) break;
    subjects.push_back(trimmed(xml.substr(at, end - at)));
  }
  return subjects;
}

// Access control grants a participant only what a grant for its certificate's subject allows:
// permissions for another subject make Cyclone refuse the participant at creation.
void check_permission_subject(const std::string& permissions, const std::string& path, X509* cert,
                              const std::string& cert_path) {
  const NameParts subject = name_parts(X509_get_subject_name(cert));
  const std::vector<std::string> granted = permission_subjects(permissions);
  for (const std::string& text : granted) {
    if (cyclone_grants(text, subject)) return;
  }
  for (const std::string& text : granted) {
    if (!same_name(name_parts(text), subject)) continue;
    fail(path, "permissions subject \"" + text + "\" is the certificate " + cert_path +
                   "'s subject as an X.509 name, but Cyclone's access control compares it "
                   "attribute by attribute as written (short names, no spaces): write \"" +
                   name_text(subject) + "\"");
  }
  std::string listed;
  for (const std::string& text : granted) listed += (listed.empty() ? "\"" : ", \"") + text + "\"";
  fail(path, "permissions document is for subject " +
                 (listed.empty() ? std::string("(no <subject_name>)") : listed) +
                 ", not for the certificate " + cert_path + "'s subject \"" + name_text(subject) +
                 "\" (make this identity's permissions again with `hq-keys identity`)");
}

// A station's writers are also in its station partitions (keys.hpp: per-station identity), so
// its permissions must grant those for every vehicle they grant: a keyset made before identities
// were bound to certificates would have every station writer refused at run time.
void check_station_partitions(const std::string& permissions, const std::string& path, X509* cert) {
  std::uint32_t station = 0;
  for (const auto& [key, value] : name_parts(X509_get_subject_name(cert))) {
    if (key != "CN" || value.rfind("station_", 0) != 0) continue;
    const std::string_view digits = std::string_view(value).substr(8);
    const auto [end, error] =
        std::from_chars(digits.data(), digits.data() + digits.size(), station);
    if (error != std::errc() || end != digits.data() + digits.size()) station = 0;
  }
  if (station == 0) return;  // not a station of the hq-keys layout
  const std::size_t open = permissions.find("<publish>");
  const std::size_t close = permissions.find("</publish>", open);
  if (open == std::string::npos || close == std::string::npos) return;
  const std::string publish = permissions.substr(open, close - open);
  static constexpr std::string_view kPartition = "<partition>hq_vehicle_";
  for (std::size_t at = publish.find(kPartition); at != std::string::npos;
       at = publish.find(kPartition, at + 1)) {
    const std::size_t begin = at + kPartition.size();
    const std::size_t end = publish.find('<', begin);
    std::uint32_t vehicle = 0;
    const auto [digits_end, error] =
        std::from_chars(publish.data() + begin, publish.data() + end, vehicle);
    if (error != std::errc() || digits_end != publish.data() + end) continue;  // a station's
    const std::string wanted = "<partition>" + station_partition(vehicle, station) + "</partition>";
    if (publish.find(wanted) == std::string::npos) {
      fail(path, "permissions of station_" + std::to_string(station) + " grant vehicle " +
                     std::to_string(vehicle) + " but not its station partition " +
                     station_partition(vehicle, station) +
                     ", which binds what it writes to its certificate: made by an older "
                     "hq-keys; make this identity again (hq-keys identity KEYS --role station "
                     "--id " +
                     std::to_string(station) + " --vehicles ...)");
    }
  }
}

// "SHA-256 12:AB:...": a CA's fingerprint, which tells apart two CAs of the same name (every
// `hq-keys init` makes a "CN=HaptiQuad CA").
std::string fingerprint(X509* cert) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  require(X509_digest(cert, EVP_sha256(), md, &n) == 1, "X509_digest", "SHA-256");
  std::string text = "SHA-256 ";
  for (unsigned int i = 0; i < std::min(n, 8U); ++i) {
    fmt::format_to(std::back_inserter(text), "{}{:02X}", i == 0 ? "" : ":", md[i]);
  }
  return text + ":...";
}

std::string ca_text(const std::string& path, X509* ca) {
  return path + " (\"" + name_text(name_parts(X509_get_subject_name(ca))) + "\", " +
         fingerprint(ca) + ")";
}

// Whether `cert` chains to `ca` at `now_s`, as a peer's authentication plugin verifies it.
bool chains_to(X509* cert, X509* ca, std::int64_t now_s) {
  Owned<X509_STORE> store(X509_STORE_new());
  require(store != nullptr && X509_STORE_add_cert(store.get(), ca) == 1, "X509_STORE_add_cert",
          "CA");
  std::unique_ptr<X509_STORE_CTX, decltype(&X509_STORE_CTX_free)> ctx(X509_STORE_CTX_new(),
                                                                      &X509_STORE_CTX_free);
  require(ctx != nullptr && X509_STORE_CTX_init(ctx.get(), store.get(), cert, nullptr) == 1,
          "X509_STORE_CTX_init", "failed");
  X509_STORE_CTX_set_time(ctx.get(), 0, static_cast<time_t>(now_s));
  const bool ok = X509_verify_cert(ctx.get()) == 1;
  ERR_clear_error();
  return ok;
}

}  // namespace

std::string vehicle_partition(std::uint32_t vehicle_id) {
  return "hq_vehicle_" + std::to_string(vehicle_id);
}

std::string station_partition(std::uint32_t vehicle_id, std::uint32_t station_id) {
  return vehicle_partition(vehicle_id) + "_station_" + std::to_string(station_id);
}

std::uint32_t station_of_partition(std::string_view partition, std::uint32_t vehicle_id) {
  const std::string prefix = vehicle_partition(vehicle_id) + "_station_";
  if (partition.size() <= prefix.size() || partition.substr(0, prefix.size()) != prefix) return 0;
  const std::string_view digits = partition.substr(prefix.size());
  std::uint32_t id = 0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  // Canonical decimal only: "07" or "7x" are not a partition hq-keys grants.
  if (error != std::errc() || end != digits.data() + digits.size() || digits.front() == '0') {
    return 0;
  }
  return id;
}

std::string identity_name(Role role, std::uint32_t id) {
  return std::string(role_word(role)) + "_" + std::to_string(id);
}

std::string subject_name(Role role, std::uint32_t id) {
  return "CN=" + identity_name(role, id) + ",O=HaptiQuad";
}

IdentityFiles files_in(const std::string& keys_dir, const std::string& identity) {
  const std::string own = keys_dir + "/" + identity + "/";
  return {keys_dir + "/ca.pem",         own + "cert.pem",        own + "key.pem",
          keys_dir + "/governance.p7s", own + "permissions.p7s", keys_dir + "/ca.pem"};
}

Validity valid_for_days(std::int64_t now_s, int days) {
  return {now_s - 60, now_s + static_cast<std::int64_t>(days) * 86'400};
}

void make_ca(const std::string& dir, const Validity& validity) {
  const IdentityFiles files = files_in(dir, "");
  if (std::filesystem::exists(files.identity_ca)) {
    fail(files.identity_ca, "a CA exists already; remove the directory to start over");
  }
  make_dir(dir);
  Owned<EVP_PKEY> key = make_key();
  Owned<X509> cert = make_cert(key.get(), "HaptiQuad CA", validity, nullptr, nullptr);
  write_file(dir + "/ca.key.pem", key_pem(key.get()), true);
  write_file(files.identity_ca, cert_pem(cert.get()));
}

std::string governance_xml(const DomainRange& domains) {
  check_domains(domains);
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\"\n"
         "     xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
         "omg_shared_ca_governance.xsd\">\n"
         "  <domain_access_rules>\n"
         "    <domain_rule>\n"
      << domains_xml(domains, "      ")
      << "      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>\n"
         "      <enable_join_access_control>true</enable_join_access_control>\n"
         "      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>\n"
         "      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>\n"
         // Payloads are encrypted per topic below; whole-message protection would add a second
         // AES-GCM pass per packet for nothing on top.
         "      <rtps_protection_kind>NONE</rtps_protection_kind>\n"
         "      <topic_access_rules>\n"
         "        <topic_rule>\n"
         "          <topic_expression>hq_*</topic_expression>\n"
         "          <enable_discovery_protection>true</enable_discovery_protection>\n"
         "          <enable_liveliness_protection>true</enable_liveliness_protection>\n"
         "          <enable_read_access_control>true</enable_read_access_control>\n"
         "          <enable_write_access_control>true</enable_write_access_control>\n"
         "          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>\n"
         "          <data_protection_kind>ENCRYPT</data_protection_kind>\n"
         "        </topic_rule>\n"
         "      </topic_access_rules>\n"
         "    </domain_rule>\n"
         "  </domain_access_rules>\n"
         "</dds>\n";
  return xml.str();
}

std::string permissions_xml(const IdentityRequest& request) {
  check_domains(request.domains);
  const bool vehicle = request.role == Role::kVehicle;
  const std::vector<std::uint32_t> vehicles =
      vehicle ? std::vector<std::uint32_t>{request.id} : request.vehicles;
  if (vehicles.empty()) {
    throw InputError("station " + std::to_string(request.id) +
                     ": no vehicles to command (expected --vehicles ID[,ID...])");
  }
  // What each end writes and reads (the link's topic table in hq/link/qos.hpp).
  const std::vector<const char*> vehicle_writes = {"hq_vehicle_state", "hq_camera_frame",
                                                   "hq_event", "hq_heartbeat"};
  const std::vector<const char*> station_writes = {"hq_velocity_command", "hq_mode_request",
                                                   "hq_heartbeat"};
  // Both ends read every link topic of their vehicles: each has a flight log (hq-ground
  // --record, hq-onboard --record) that records what was sent both ways, on a participant of its
  // own. Neither can write what the other end writes.
  std::vector<const char*> all_reads = vehicle_writes;
  all_reads.insert(all_reads.end(), {"hq_velocity_command", "hq_mode_request"});
  const auto& publishes = vehicle ? vehicle_writes : station_writes;
  const auto& subscribes = all_reads;
  // A station publishes in its own station partitions as well (keys.hpp: per-station
  // identity); access control wants every partition of a writer granted by one criterion.
  const auto criteria = [&](const char* kind, const std::vector<const char*>& topics,
                            bool with_station) {
    std::ostringstream xml;
    xml << "        <" << kind << ">\n          <topics>\n";
    for (const char* topic : topics) xml << "            <topic>" << topic << "</topic>\n";
    xml << "          </topics>\n          <partitions>\n";
    for (const std::uint32_t v : vehicles) {
      xml << "            <partition>" << vehicle_partition(v) << "</partition>\n";
      if (with_station) {
        xml << "            <partition>" << station_partition(v, request.id) << "</partition>\n";
      }
    }
    xml << "          </partitions>\n        </" << kind << ">\n";
    return xml.str();
  };
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\"\n"
         "     xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
         "omg_shared_ca_permissions.xsd\">\n"
         "  <permissions>\n"
      << "    <grant name=\"" << identity_name(request.role, request.id) << "\">\n"
      << "      <subject_name>" << subject_name(request.role, request.id) << "</subject_name>\n"
      << "      <validity>\n"
      << "        <not_before>" << iso_utc(request.validity.not_before_s) << "</not_before>\n"
      << "        <not_after>" << iso_utc(request.validity.not_after_s) << "</not_after>\n"
      << "      </validity>\n"
      << "      <allow_rule>\n"
      << domains_xml(request.domains, "        ") << criteria("publish", publishes, !vehicle)
      << criteria("subscribe", subscribes, false)
      << "      </allow_rule>\n"
         "      <default>DENY</default>\n"
         "    </grant>\n"
         "  </permissions>\n"
         "</dds>\n";
  return xml.str();
}

void make_governance(const std::string& dir, const DomainRange& domains) {
  const Ca ca = load_ca(dir);
  const std::string xml = governance_xml(domains);
  write_file(dir + "/governance.xml", xml);
  write_file(dir + "/governance.p7s", smime_sign(xml, ca.cert.get(), ca.key.get()));
}

void make_identity(const std::string& dir, const IdentityRequest& request) {
  if (request.validity.not_after_s <= request.validity.not_before_s) {
    throw InputError("identity " + identity_name(request.role, request.id) +
                     ": validity ends before it starts");
  }
  const Ca ca = load_ca(dir);
  const std::string xml = permissions_xml(request);
  const std::string name = identity_name(request.role, request.id);
  const IdentityFiles files = files_in(dir, name);
  make_dir(dir + "/" + name);
  Owned<EVP_PKEY> key = make_key();
  Owned<X509> cert = make_cert(key.get(), name, request.validity, ca.cert.get(), ca.key.get());
  write_file(files.private_key, key_pem(key.get()), true);
  write_file(files.certificate, cert_pem(cert.get()));
  write_file(dir + "/" + name + "/permissions.xml", xml);
  write_file(files.permissions, smime_sign(xml, ca.cert.get(), ca.key.get()));
}

void check_identity(const IdentityFiles& files, std::int64_t now_s) {
  check_readable(files.identity_ca, "identity CA certificate");
  check_readable(files.certificate, "identity certificate");
  check_readable(files.private_key, "private key");
  check_readable(files.governance, "governance document");
  check_readable(files.permissions, "permissions document");
  check_readable(files.permissions_ca, "permissions CA certificate");
  const Owned<X509> ca = load_cert(files.identity_ca);
  check_times(ca.get(), files.identity_ca, "identity CA certificate", now_s);
  const Owned<X509> cert = load_cert(files.certificate);
  check_times(cert.get(), files.certificate, "certificate", now_s);
  if (X509_verify(cert.get(), X509_get0_pubkey(ca.get())) != 1) {
    ERR_clear_error();
    fail(files.certificate, "certificate was not signed by the identity CA " + files.identity_ca);
  }
  const Owned<EVP_PKEY> key = load_key(files.private_key);
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    ERR_clear_error();
    fail(files.private_key, "private key does not match the certificate " + files.certificate);
  }
  const Owned<X509> permissions_ca = load_cert(files.permissions_ca);
  check_times(permissions_ca.get(), files.permissions_ca, "permissions CA certificate", now_s);
  check_signed(files.governance, "governance document", permissions_ca.get(), files.permissions_ca);
  const std::string permissions = check_signed(files.permissions, "permissions document",
                                               permissions_ca.get(), files.permissions_ca);
  check_permission_subject(permissions, files.permissions, cert.get(), files.certificate);
  check_station_partitions(permissions, files.permissions, cert.get());
}

namespace {

// Why `from` cannot authenticate to `to` (empty when it can): `to` verifies `from`'s certificate
// with its identity CA and `from`'s permissions with its permissions CA.
std::string trust_problems(const Peer& from, const std::string& to_name, X509* to_identity_ca,
                           const std::string& to_identity_ca_path, X509* to_permissions_ca,
                           const std::string& to_permissions_ca_path, std::int64_t now_s) {
  std::string problems;
  const Owned<X509> cert = load_cert(from.files.certificate);
  if (!chains_to(cert.get(), to_identity_ca, now_s)) {
    const Owned<X509> own_ca = load_cert(from.files.identity_ca);
    problems += from.name + "'s certificate " + from.files.certificate + " is signed by CA " +
                ca_text(from.files.identity_ca, own_ca.get()) + ", " + to_name + " trusts CA " +
                ca_text(to_identity_ca_path, to_identity_ca);
  }
  std::string why;
  if (!verified_content(from.files.permissions, "permissions document", to_permissions_ca,
                        to_permissions_ca_path, why)) {
    const Owned<X509> own_ca = load_cert(from.files.permissions_ca);
    problems += std::string(problems.empty() ? "" : "; ") + from.name + "'s permissions " +
                from.files.permissions + " are signed by CA " +
                ca_text(from.files.permissions_ca, own_ca.get()) + ", " + to_name +
                " trusts permissions from CA " + ca_text(to_permissions_ca_path, to_permissions_ca);
  }
  return problems;
}

std::string trust_problems(const Peer& from, const Peer& to, std::int64_t now_s) {
  const Owned<X509> identity_ca = load_cert(to.files.identity_ca);
  const Owned<X509> permissions_ca = load_cert(to.files.permissions_ca);
  return trust_problems(from, to.name, identity_ca.get(), to.files.identity_ca,
                        permissions_ca.get(), to.files.permissions_ca, now_s);
}

[[noreturn]] void fail_handshake(const std::string& a, const std::string& b,
                                 const std::string& problems) {
  throw InputError("a handshake between " + a + " and " + b + " cannot succeed: " + problems +
                   " (make both identities with one CA: `hq-keys identity` on the same keys "
                   "directory)");
}

}  // namespace

void check_handshake(const Peer& a, const Peer& b, std::int64_t now_s) {
  check_identity(a.files, now_s);
  check_identity(b.files, now_s);
  const std::string a_to_b = trust_problems(a, b, now_s);
  const std::string b_to_a = trust_problems(b, a, now_s);
  if (a_to_b.empty() && b_to_a.empty()) return;
  fail_handshake(a.name, b.name, a_to_b + (a_to_b.empty() || b_to_a.empty() ? "" : "; ") + b_to_a);
}

void check_trusted_by(const Peer& a, const std::string& peer_ca, std::int64_t now_s) {
  check_identity(a.files, now_s);
  check_readable(peer_ca, "peer's CA certificate");
  const Owned<X509> ca = load_cert(peer_ca);
  check_times(ca.get(), peer_ca, "peer's CA certificate", now_s);
  const std::string problems =
      trust_problems(a, "the peer", ca.get(), peer_ca, ca.get(), peer_ca, now_s);
  if (!problems.empty()) fail_handshake(a.name, "a peer trusting " + peer_ca, problems);
}

}  // namespace hq::security
