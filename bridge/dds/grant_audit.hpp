#pragma once
// Every grant of a permissions document compared with what `linebridge-security permissions`
// generates for its role (security_policy.cpp), so that a hand-edited grant signed with
// `pki.sh sign` cannot quietly give a client more than its role. Fast DDS enforces whatever the
// permissions CA signed; this is the line's own judgement of it, made before start
// (`linebridge --check`, `linebridge-security check [--identity DIR]`, and the bridge's start for
// its own permissions file, every grant in it).
//
// Refused (errors):
//  - a publish right (topic, partition) that the role's generated grant does not have: an extra
//    topic (another line's, an unknown device's, a topic only the bridge writes), or a wildcard
//    (`*`, `?`, `[...]`) in a topic or a partition other than the ones pki.sh itself writes
//    (an engineer issued without --devices may command every device: `rt/<line>/*/setpoint`,
//    partition `*`);
//  - a bridge grant (publishing what only the bridge writes, e.g. `rt/<line>/*`) for any subject
//    but the bridge's own identity;
//  - <default>ALLOW</default> (everything no rule names is allowed).
// Warned: subscribe rights beyond the role's. Reading cannot move a machine, and the generated
// grants already read with wildcards (`rt/<line>/*/status`), so a monitoring tool given wider
// read rights is a decision to see, not a set-up that endangers the line; a warning names it.
//
// Refused too: a document Fast DDS 2.9.1's parser refuses (an element it does not take, a rule
// without <domains>, a <grant> without <default>, ...), with the reason and the line: Fast DDS
// itself says only "Malformed permissions file". Warned: what Fast DDS reads but does not enforce
// (<data_tags>) or never reads (anything after <default>).
//
// The rights are read as Fast DDS reads them (grant_audit.cpp says how): every <topics> and
// <partitions>, every <publish>, <subscribe> and <relay> of a rule together, texts as written, a
// rule's domains as Fast DDS matches them. Deny rules are not credited: they only take rights
// away, and only where they come first.
//
// The role is the one the grant's name gives (pki.sh names grants <line>_<role>); a grant named
// otherwise is judged against the smallest client role that has all its publish rights, or
// against the engineer's (the widest client role) when none has.

#include <cstdint>
#include <string>
#include <vector>

namespace lb::ddsl {

struct SecurityFiles;

struct GrantPolicy {
  std::string line;
  std::vector<std::string> devices;  // the line's devices
  std::string bridge_subject;        // the bridge's identity (RFC 2253); empty: not known here
};

struct GrantFindings {
  std::vector<std::string> errors;
  std::vector<std::string> warnings;
};

// The grants of a permissions document (its signed content) on `domain`.
GrantFindings audit_grants(const std::string& permissions_xml, const GrantPolicy& policy, std::uint32_t domain);

// The warnings of the files' permissions document under files.grant_policy (none without one),
// read without verifying its signature: check_security_files verifies it and reports the errors.
std::vector<std::string> grant_warnings(const SecurityFiles& files, std::uint32_t domain);

}  // namespace lb::ddsl
