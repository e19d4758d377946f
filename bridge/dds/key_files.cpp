#include "dds/key_files.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <set>

#include "dds/openssl_ptr.hpp"

namespace lb::ddsl {
namespace {

namespace fs = std::filesystem;
// Larger files are no PEM key; they are not read.
constexpr std::uintmax_t kMaxKeyFile = 64 * 1024;

std::string mode_text(mode_t mode) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04o", static_cast<unsigned>(mode & 07777));
  return buf;
}

// The CAs' public keys, with the subject to name them by.
struct CaKey {
  std::string subject;
  ossl::Key key;
};

std::vector<CaKey> ca_public_keys(const std::vector<std::string>& ca_certificates) {
  std::vector<CaKey> out;
  for (const auto& path : ca_certificates) {
    std::string why;
    const auto pem = ossl::read_whole_file(path, why);
    if (!pem) continue;
    for (const auto& c : ossl::read_certificates(*pem)) {
      if (EVP_PKEY* k = X509_get_pubkey(c.get()))
        out.push_back({ossl::name_text(X509_get_subject_name(c.get())), ossl::Key(k)});
    }
  }
  return out;
}

// An unencrypted PEM private key in `pem`, or null (encrypted ones cannot be compared).
ossl::Key private_key_in(const std::string& pem) {
  ossl::Bio in = ossl::memory_bio(pem);
  // A password callback that gives none: an encrypted key fails instead of prompting.
  ossl::Key key(PEM_read_bio_PrivateKey(
      in.get(), nullptr, [](char*, int, int, void*) { return 0; }, nullptr));
  ERR_clear_error();
  return key;
}

}  // namespace

std::optional<std::string> private_key_mode_problem(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::nullopt;
  if ((st.st_mode & 077) == 0) return std::nullopt;
  return "mode " + mode_text(st.st_mode) +
         " gives group or others access to the private key: only its owner may read it (chmod 600 " + path + ")";
}

std::vector<FileFinding> ca_keys_beside(const std::vector<std::string>& files_in_use,
                                        const std::vector<std::string>& ca_certificates, const std::string& own_key) {
  std::set<fs::path> folders;
  for (const auto& f : files_in_use) {
    if (f.empty()) continue;
    const fs::path dir = fs::absolute(f).lexically_normal().parent_path();
    folders.insert(dir);
    folders.insert(dir / "ca");
  }
  const auto cas = ca_public_keys(ca_certificates);
  const fs::path own = own_key.empty() ? fs::path() : fs::absolute(own_key).lexically_normal();
  std::vector<FileFinding> out;
  for (const auto& dir : folders) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      std::error_code fe;
      if (!entry.is_regular_file(fe) || entry.file_size(fe) > kMaxKeyFile || fe) continue;
      const fs::path path = entry.path().lexically_normal();
      if (path == own) continue;
      std::string why;
      const auto pem = ossl::read_whole_file(path.string(), why);
      if (!pem || pem->find("PRIVATE KEY-----") == std::string::npos) continue;  // unreadable to us: good
      std::string what;
      if (ossl::Key key = private_key_in(*pem)) {
        for (const auto& ca : cas) {
          if (EVP_PKEY_eq(key.get(), ca.key.get()) == 1) what = "the private key of the CA '" + ca.subject + "'";
        }
        ERR_clear_error();
      }
      if (what.empty() && dir.filename() == "ca" && path.extension() == ".key") what = "a private key in a ca/ folder";
      if (what.empty()) continue;
      out.push_back({"CA key", path.string(),
                     what + " lies beside the identity in use (" + dir.string() +
                         "): whoever reads it can issue identities and sign permissions for the line; keep CA keys "
                         "offline (launch_scripts/pki.sh keeps them in ca-private/, to be moved away)"});
    }
  }
  return out;
}

}  // namespace lb::ddsl
