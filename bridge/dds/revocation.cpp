#include "dds/revocation.hpp"

#include <openssl/x509_vfy.h>

#include "dds/openssl_ptr.hpp"

namespace lb::ddsl {
namespace {

const char* const kRenewHint =
    "renew it with `launch_scripts/pki.sh revoke --dir DIR` (without --name it only re-issues the list)";

// Fast DDS reads the first PEM CRL of the file (FileProvider::load_crl), nothing else.
ossl::Crl first_crl(const std::string& pem) {
  ossl::Bio in = ossl::memory_bio(pem);
  ossl::Crl crl(PEM_read_bio_X509_CRL(in.get(), nullptr, nullptr, nullptr));
  ERR_clear_error();
  return crl;
}

}  // namespace

FileFindings check_identity_crl(const std::string& crl_path, const std::string& identity_ca_path,
                                const std::string& certificate_path, std::time_t now) {
  FileFindings out;
  const auto problem = [&](std::string why) { out.problems.push_back({"identity_crl", crl_path, std::move(why)}); };
  std::string why;
  const auto pem = ossl::read_whole_file(crl_path, why);
  if (!pem) return problem(why), out;
  ossl::Crl crl = first_crl(*pem);
  if (!crl) {
    problem("no PEM certificate revocation list in it (-----BEGIN X509 CRL-----)");
    return out;
  }
  const std::string issuer = ossl::name_text(X509_CRL_get_issuer(crl.get()));

  // Signed by the identity CA: the CA whose name is the CRL's issuer, and its key verifies it.
  std::string ca_why;
  const auto ca_pem = ossl::read_whole_file(identity_ca_path, ca_why);
  const auto cas = ca_pem ? ossl::read_certificates(*ca_pem) : std::vector<ossl::Cert>{};
  if (cas.empty()) return out;  // the identity CA's own problem is reported by its check
  const ossl::Cert* ca = nullptr;
  for (const auto& c : cas) {
    if (X509_NAME_cmp(X509_get_subject_name(c.get()), X509_CRL_get_issuer(crl.get())) == 0) ca = &c;
  }
  if (ca == nullptr) {
    problem("issued by '" + issuer + "', not by the identity CA " + identity_ca_path + " ('" +
            ossl::name_text(X509_get_subject_name(cas.front().get())) +
            "'): Fast DDS would then find no CRL of the identity CA and refuse every identity");
    return out;
  }
  if (X509_CRL_verify(crl.get(), X509_get0_pubkey(ca->get())) != 1) {
    ERR_clear_error();
    problem("its signature does not verify with the key of the identity CA " + identity_ca_path + " ('" + issuer +
            "'): another CA of the same name signed it, or it was changed after signing");
    return out;
  }

  // Its validity: outside it, OpenSSL fails every verification (X509_V_ERR_CRL_NOT_YET_VALID,
  // X509_V_ERR_CRL_HAS_EXPIRED), so Fast DDS would refuse its own identity and every remote one.
  std::time_t t = now;
  if (X509_cmp_time(X509_CRL_get0_lastUpdate(crl.get()), &t) > 0) {
    problem("not valid before " + ossl::time_text(X509_CRL_get0_lastUpdate(crl.get())) +
            " (its last update is in the future: is this host's clock right?)");
  }
  if (const ASN1_TIME* next = X509_CRL_get0_nextUpdate(crl.get())) {
    std::time_t soon = now + std::chrono::duration_cast<std::chrono::seconds>(kCrlRenewWarning).count();
    if (X509_cmp_time(next, &t) < 0) {
      problem("expired: its next update was " + ossl::time_text(next) +
              "; with an expired CRL Fast DDS refuses every identity of the line, this one too: " + kRenewHint);
    } else if (X509_cmp_time(next, &soon) < 0) {
      out.warnings.push_back({"identity_crl", crl_path,
                              "its next update is " + ossl::time_text(next) + ", within " +
                                  std::to_string(kCrlRenewWarning.count() / 24) +
                                  " days: after that moment a running bridge authenticates nobody new and a "
                                  "restart is refused; " +
                                  kRenewHint});
    }
  }

  // This participant's own certificate, revoked: Fast DDS refuses it (validate_local_identity).
  std::string cert_why;
  const auto cert_pem = ossl::read_whole_file(certificate_path, cert_why);
  const auto certs = cert_pem ? ossl::read_certificates(*cert_pem) : std::vector<ossl::Cert>{};
  X509_REVOKED* revoked = nullptr;
  if (!certs.empty() && X509_CRL_get0_by_cert(crl.get(), &revoked, certs.front().get()) == 1) {
    problem("it revokes this participant's own certificate " + certificate_path + " ('" +
            ossl::name_text(X509_get_subject_name(certs.front().get())) + "', revoked " +
            ossl::time_text(X509_REVOKED_get0_revocationDate(revoked)) + ")");
  }
  return out;
}

}  // namespace lb::ddsl
