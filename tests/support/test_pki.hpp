#pragma once
// DDS Security material made at test time by the real launch_scripts/pki.sh and openssl (no key is
// ever committed), identities per role, and the options of secured test participants.

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include "dds/participant.hpp"
#include "support/scratch_files.hpp"

namespace lb::test {

// Runs a shell command; its output goes to `log`. Returns the exit status.
inline int shell(const std::string& command, const std::string& log) {
  const int status = std::system(("(" + command + ") >>'" + log + "' 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class TestPki {
 public:
  // pki.sh init for the (unsecured) line file at `line_config` into `dir`: CAs, governance, bridge.
  TestPki(std::string line_config, std::string dir) : config_(std::move(line_config)), dir_(std::move(dir)) {
    // Always a new PKI: test directories are named after the pid, and pids come round again
    // (pid_max 32768); pki.sh init keeps an existing CA, whose leftover files from an earlier run
    // made `openssl ca -gencrl` fail in a clean-clone CI run.
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    log_ = dir_ + "/pki.log";
    run("init --config '" + config_ + "' --dir '" + dir_ + "'");
  }

  // pki.sh issue: an identity folder (cert.pem, key.pem, permissions.p7s) for a role.
  std::string issue(const std::string& name, const std::string& role, const std::string& devices = "") const {
    run("issue --config '" + config_ + "' --dir '" + dir_ + "' --name " + name + " --role " + role +
        (devices.empty() ? "" : " --devices " + devices));
    return dir_ + "/" + name;
  }
  // pki.sh revoke: NAME's certificate revoked, ca/identity_crl.pem re-issued.
  void revoke(const std::string& name) const { run("revoke --dir '" + dir_ + "' --name " + name); }
  // pki.sh sign: FILE.xml -> FILE.p7s with this PKI's permissions CA.
  void sign(const std::string& xml) const { run("sign --dir '" + dir_ + "' '" + xml + "'"); }
  // openssl, with this PKI's folder as the working directory; throws on failure.
  void openssl(const std::string& args) const {
    if (shell("cd '" + dir_ + "' && openssl " + args, log_) != 0) {
      throw std::runtime_error("openssl " + args + " failed:\n" + read_text(log_));
    }
  }

  const std::string& dir() const { return dir_; }
  std::string identity_ca() const { return dir_ + "/ca/identity_ca.pem"; }
  std::string permissions_ca() const { return dir_ + "/ca/permissions_ca.pem"; }
  std::string governance() const { return dir_ + "/governance.p7s"; }
  std::string identity_crl() const { return dir_ + "/ca/identity_crl.pem"; }

  // The dds.security block of a line file for an identity folder (the bridge's by default).
  std::string security_yaml(const std::string& identity = "") const {
    const std::string id = identity.empty() ? dir_ + "/bridge" : identity;
    return "  security:\n"
           "    identity_ca: " +
           identity_ca() +
           "\n"
           "    permissions_ca: " +
           permissions_ca() +
           "\n"
           "    governance: " +
           governance() +
           "\n"
           "    certificate: " +
           id +
           "/cert.pem\n"
           "    private_key: " +
           id +
           "/key.pem\n"
           "    permissions: " +
           id +
           "/permissions.p7s\n"
           "    identity_crl: " +
           identity_crl() + "\n";
  }

  // The files of a secured test participant with this identity.
  ddsl::SecurityFiles files(const std::string& identity) const {
    return {identity_ca(),
            identity + "/cert.pem",
            identity + "/key.pem",
            permissions_ca(),
            governance(),
            identity + "/permissions.p7s",
            {},
            identity_crl()};
  }
  ddsl::ParticipantOptions options(std::uint32_t domain, const std::string& identity, const std::string& name) const {
    return {domain, true, name, files(identity)};
  }

 private:
  void run(const std::string& args) const {
    const std::string bin = std::filesystem::path(LB_BIN_BRIDGE).parent_path().string();
    if (shell("LINEBRIDGE_BIN='" + bin + "' '" LB_SOURCE_DIR "/launch_scripts/pki.sh' " + args, log_) != 0) {
      throw std::runtime_error("pki.sh " + args + " failed:\n" + read_text(log_));
    }
  }

  std::string config_;
  std::string dir_;
  std::string log_;
};

}  // namespace lb::test
