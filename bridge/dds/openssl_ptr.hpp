#pragma once
// OpenSSL objects owned by unique_ptr (F is the library's own free function), and the small
// readers the checks of the security files share: a whole file, PEM certificates, names as Fast
// DDS prints them.

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include "base/bounded_file.hpp"

#include <cerrno>
#include <memory>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

namespace lb::ddsl::ossl {

template <auto F>
struct Free {
  template <class T>
  void operator()(T* p) const {
    F(p);
  }
};
using Bio = std::unique_ptr<BIO, Free<BIO_free_all>>;
using Cert = std::unique_ptr<X509, Free<X509_free>>;
using Crl = std::unique_ptr<X509_CRL, Free<X509_CRL_free>>;
using Key = std::unique_ptr<EVP_PKEY, Free<EVP_PKEY_free>>;
using Store = std::unique_ptr<X509_STORE, Free<X509_STORE_free>>;
using StoreCtx = std::unique_ptr<X509_STORE_CTX, Free<X509_STORE_CTX_free>>;

inline Bio memory_bio(const std::string& bytes) {
  return Bio(BIO_new_mem_buf(bytes.data(), static_cast<int>(bytes.size())));
}

inline std::string bio_text(BIO* bio) {
  BUF_MEM* mem = nullptr;
  BIO_get_mem_ptr(bio, &mem);
  return mem == nullptr ? std::string() : std::string(mem->data, mem->length);
}

// RFC 2253 order, most specific first, as Fast DDS prints subjects (PKIDH.cpp).
inline std::string name_text(const X509_NAME* name) {
  Bio out(BIO_new(BIO_s_mem()));
  X509_NAME_print_ex(out.get(), name, 0, XN_FLAG_RFC2253 & ~ASN1_STRFLGS_ESC_MSB);
  return bio_text(out.get());
}

inline std::string time_text(const ASN1_TIME* t) {
  Bio out(BIO_new(BIO_s_mem()));
  ASN1_TIME_print(out.get(), t);
  return bio_text(out.get());
}

inline std::vector<Cert> read_certificates(const std::string& pem) {
  std::vector<Cert> certs;
  Bio in = memory_bio(pem);
  while (X509* c = PEM_read_bio_X509(in.get(), nullptr, nullptr, nullptr)) certs.emplace_back(c);
  ERR_clear_error();  // the end of the file reads as an error
  return certs;
}

// The whole file, or nullopt with the reason in `why`: a regular file of at most 1 MiB (no
// certificate, key or signed document comes near; a FIFO would block, /dev/zero never end).
inline constexpr std::size_t kMaxSecurityFileBytes = 1024 * 1024;
inline std::optional<std::string> read_whole_file(const std::string& path, std::string& why) {
  auto text = read_bounded_file(path, "security file", kMaxSecurityFileBytes);
  if (!text) {
    // The callers name the file: only the reason after "PATH: security file: ".
    const auto& message = text.error().message;
    const auto prefix = path + ": security file: ";
    why = message.rfind(prefix, 0) == 0 ? message.substr(prefix.size()) : message;
    if (why.rfind("cannot open: ", 0) == 0) why = "cannot read it: " + why.substr(13);  // the wording operators know
    return std::nullopt;
  }
  return std::move(*text);
}

}  // namespace lb::ddsl::ossl
