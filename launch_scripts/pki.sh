#!/usr/bin/env bash
# The DDS Security material of a line, with openssl: two CAs, the signed governance, and signed
# identities (certificate, key, permissions) per role. docs/security.md explains the whole.
#
#   launch_scripts/pki.sh init  --config LINE.yaml --dir DIR [--ca-dir CADIR] [--org NAME] [--days N]
#       DIR/ca/                 identity CA and permissions CA certificates, identity_crl.pem (no key)
#       CADIR (DIR/ca-private/) the CA keys and the CA's records: take it offline, the bridge never
#                               needs it (linebridge warns of a CA key beside the identity in use)
#       DIR/governance.p7s      the domain's governance, signed (governance.xml: what was signed)
#       DIR/bridge/             the bridge's identity: cert.pem key.pem permissions.p7s
#       and prints the dds.security block for the line file: its security: key, indented as it
#       goes under the line file's dds: (paste it as printed below the dds: line).
#   launch_scripts/pki.sh issue --config LINE.yaml --dir DIR --name NAME --role ROLE [--devices D1,D2] [--days N]
#       DIR/NAME/               cert.pem key.pem permissions.p7s (permissions.xml: what was signed)
#       ROLE: observer (reads status, events, info, diagnostics), operator (also set values and
#       momentary/feeder commands of --devices, required), engineer (also NMT, SDO, parameters,
#       feeder configuration; of --devices, default every device), bridge.
#       Every certificate issued is recorded (CADIR/identity_ca.index: serial, not-after, subject;
#       a copy in CADIR/identity_ca.issued/SERIAL.pem). Issuing a NAME again replaces DIR/NAME/
#       but not the earlier certificate: it stays valid until revoked, and issue says so with its
#       serial.
#   launch_scripts/pki.sh list  --dir DIR [--name NAME]
#       the recorded certificates (of NAME): status (valid, revoked, expired), serial, not-after
#       (UTC), subject.
#   launch_scripts/pki.sh sign  --dir DIR FILE.xml
#       signs a governance or permissions document you edited by hand -> FILE.p7s
#   launch_scripts/pki.sh revoke --dir DIR [--name NAME] [--serial SERIAL]... [CERT.pem...] [--days N]
#       revokes every certificate of NAME not yet revoked (each one issued under that name, and
#       DIR/NAME/cert.pem) and says how many, the certificate of each SERIAL (as list prints it)
#       and each CERT.pem, then re-issues DIR/ca/identity_crl.pem, valid N days; with none of
#       them it only re-issues the list (do that before its next update passes).
#       Takes effect when the bridge (and each client) restarts: a running participant keeps the
#       list it read at start.
# issue, list, sign and revoke take --ca-dir too (default DIR/ca-private, or DIR/ca where an
# older pki.sh left the keys).
#
# ECDSA P-256 keys, SHA-256 signatures (what Fast DDS 2.9 accepts), subjects CN=<name>,O=<org>,
# random 159-bit serials (openssl ca -rand_serial). A pki.sh before the records signed with
# openssl x509 and kept none: a certificate it issued is recorded when found in DIR/NAME/ (by
# issue before it replaces it, and by revoke --name); one it replaced already can only be revoked
# from its file (revoke CERT.pem).
# linebridge-security (built with the bridge) writes the XML from the line file; LINEBRIDGE_BIN
# names its folder (default: build/bridge/app, or where PATH finds it, as the package installs it).
set -euo pipefail

usage() { awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 2; }
die() { echo "pki.sh: $*" >&2; exit 2; }

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -ge 1 ] || usage
cmd=$1; shift
[[ $cmd =~ ^(init|issue|list|sign|revoke)$ ]] || usage
config="" dir="" cadir="" org="linebridge" days=365 name="" role="" devices=""
files=() serials=()
while (($#)); do
  case "$1" in
    --config) config=${2:?}; shift ;;
    --dir) dir=${2:?}; shift ;;
    --ca-dir) cadir=${2:?}; shift ;;
    --org) org=${2:?}; shift ;;
    --days) days=${2:?}; shift ;;
    --name) name=${2:?}; shift ;;
    --serial) serials+=("${2:?}"); shift ;;
    --role) role=${2:?}; shift ;;
    --devices) devices=${2:?}; shift ;;
    -h|--help) usage ;;
    -*) die "unknown option $1" ;;
    *) files+=("$1") ;;
  esac
  shift
done
[ -n "$dir" ] || die "--dir is required"
[[ $days =~ ^[1-9][0-9]*$ ]] || die "--days takes a positive number"
[[ $org =~ ^[A-Za-z0-9_.\ -]+$ ]] || die "--org: letters, digits, space, '.', '_' and '-' only"
[ -z "$name" ] || [[ $name =~ ^[A-Za-z0-9_-]+$ ]] || die "--name: letters, digits, '_' and '-' only"
command -v openssl >/dev/null || die "openssl is missing (launch_scripts/setup.sh installs it)"
# Where the CA keys are: --ca-dir, else DIR/ca-private, else DIR/ca (as pki.sh left them before).
if [ -z "$cadir" ]; then
  cadir="$dir/ca-private"
  if [ ! -f "$cadir/identity_ca.key" ] && [ -f "$dir/ca/identity_ca.key" ]; then
    cadir="$dir/ca"
    # init too: it keeps an existing CA, and its key is where that pki.sh left it.
    [ "$cmd" != init ] || echo "pki.sh: the CA keys are in $dir/ca, beside what the bridge reads (an older pki.sh put them there): move them to $dir/ca-private and take that folder offline" >&2
  fi
fi
index="$cadir/identity_ca.index" issued="$cadir/identity_ca.issued"

bin=${LINEBRIDGE_BIN:-$root/build/bridge/app}
if [ -z "${LINEBRIDGE_BIN:-}" ] && [ ! -x "$bin/linebridge-security" ] && command -v linebridge-security >/dev/null; then
  bin=$(dirname "$(command -v linebridge-security)")
fi
security() {
  [ -x "$bin/linebridge-security" ] || die "$bin/linebridge-security is missing: build first (cmake --build build)"
  "$bin/linebridge-security" ${config:+--config "$config"} "$@"
}

sign() {  # XML -> XML.p7s, signed by the permissions CA with -text (Fast DDS verifies the text header)
  local xml=$1
  openssl smime -sign -text -in "$xml" -out "${xml%.xml}.p7s" \
    -signer "$dir/ca/permissions_ca.pem" -inkey "$cadir/permissions_ca.key"
}

new_ca() {  # NAME CN
  local base="$dir/ca/$1"
  [ -f "$base.pem" ] && { echo "pki.sh: keeping $base.pem" >&2; return; }
  openssl req -x509 -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 -days $((days * 10)) \
    -keyout "$cadir/$1.key" -out "$base.pem" -subj "/O=$org/CN=$2" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" 2>/dev/null
  chmod 600 "$cadir/$1.key"
}

# The identity CA's records for `openssl ca`, beside its key: the index of every certificate it
# issued or revoked (status, not-after, revocation date, serial, subject), a copy of each issued
# certificate (SERIAL.pem), the CRL numbers. -preserveDN keeps the subject as requested (O, CN);
# unique_subject = no lets a name be issued again.
ca_config() {
  [ -f "$index" ] || : >"$index"
  mkdir -p "$issued"
  [ -f "$cadir/identity_ca.crlnumber" ] || echo 01 >"$cadir/identity_ca.crlnumber"
  printf '[ca]\ndefault_ca = lb\n[lb]\ndatabase = %s\nnew_certs_dir = %s\nserial = %s\ncrlnumber = %s\ndefault_md = sha256\ndefault_crl_days = %s\nunique_subject = no\npolicy = lb_policy\n[lb_policy]\norganizationName = supplied\ncommonName = supplied\n' \
    "$index" "$issued" "$cadir/identity_ca.serial" "$cadir/identity_ca.crlnumber" "$days" >"$cadir/identity_ca.cnf"
}
ca() { openssl ca -batch -config "$cadir/identity_ca.cnf" -keyfile "$cadir/identity_ca.key" -cert "$dir/ca/identity_ca.pem" "$@"; }

crl() {  # re-issues DIR/ca/identity_crl.pem from the records, valid --days
  ca_config
  ca -gencrl -out "$dir/ca/identity_crl.pem" 2>/dev/null || die "openssl ca -gencrl failed"
  echo "pki.sh: $dir/ca/identity_crl.pem: next update $(openssl crl -noout -nextupdate -in "$dir/ca/identity_crl.pem" | sed 's/^nextUpdate=//')" >&2
}

# The records, one line each: status (valid, revoked, expired), serial, not-after (UTC,
# YYYY-MM-DD hh:mm), subject; of NAME only when given (its CN). A serial as openssl prints it,
# upper-case hex; --serial also takes lower case, colons and leading zeros.
records() {  # [NAME]
  [ -f "$index" ] || return 0
  awk -F'\t' -v name="${1:-}" -v now="$(date -u +%Y%m%d%H%M%S)" '
    function full(t) { return (length(t) == 13 ? (substr(t, 1, 2) < 50 ? "20" : "19") : "") substr(t, 1, length(t) - 1) }
    {
      if (name != "" && $6 !~ ("/CN=" name "(/|$)")) next
      end = full($2)
      status = $1 == "R" ? "revoked" : (end < now ? "expired" : "valid")
      printf "%s\t%s\t%s-%s-%s %s:%s\t%s\n", status, $4, substr(end, 1, 4), substr(end, 5, 2), substr(end, 7, 2), substr(end, 9, 2), substr(end, 11, 2), $6
    }' "$index"
}
norm_serial() {
  local s=${1^^}
  s=${s//:/} s=${s#0X}
  while [[ $s == 0?* ]]; do s=${s#0}; done
  echo "$s"
}

serial_of() { openssl x509 -noout -serial -in "$1" | sed 's/^serial=//'; }
subject_of() { openssl x509 -noout -subject -nameopt RFC2253 -in "$1" | sed 's/^subject=//'; }
issued_here() { openssl verify -CAfile "$dir/ca/identity_ca.pem" -partial_chain "$1" >/dev/null 2>&1; }

# A certificate of this CA that a pki.sh before the records issued, found in a file: recorded
# (openssl ca -valid) and copied to the records, so that list and revoke --name find it.
record() {  # CERT.pem
  local cert=$1 serial
  [ -f "$cert" ] && issued_here "$cert" || return 0
  serial=$(serial_of "$cert")
  records | cut -f2 | grep -x "$serial" >/dev/null && return 0
  ca_config
  ca -valid "$cert" >/dev/null 2>&1 || die "cannot record $cert in $index"
  cp "$cert" "$issued/$serial.pem"
  echo "pki.sh: recorded $cert (serial $serial), issued before pki.sh kept records" >&2
}

revoke_file() {  # CERT.pem
  local cert=$1 serial
  [ -f "$cert" ] || die "revoke: no certificate $cert"
  ca_config
  ca -revoke "$cert" 2>&1 | grep -v -e '^Using configuration' -e '^Revoking Certificate' -e '^Database updated' >&2 || true
  serial=$(serial_of "$cert")
  grep -q "^R.*	$serial	" "$index" ||
    die "revoke: $cert is not in the revocation records (not issued by $dir/ca/identity_ca.pem?)"
  echo "pki.sh: revoked serial $serial '$(subject_of "$cert")'" >&2
}

issue() {  # NAME ROLE [DEVICES]
  local who=$1 as=$2 devs=${3:-} out="$dir/$1" serial earlier
  [ -n "$who" ] || die "--name is required"
  [ -f "$dir/ca/identity_ca.pem" ] || die "$dir has no CAs: run pki.sh init first"
  [ -f "$cadir/identity_ca.key" ] || die "no CA key in $cadir: give the folder with --ca-dir"
  mkdir -p "$out"
  record "$out/cert.pem"
  openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 \
    -keyout "$out/key.pem" -out "$out/request.csr" -subj "/O=$org/CN=$who" 2>/dev/null
  chmod 600 "$out/key.pem"
  ca_config
  ca -preserveDN -notext -rand_serial -md sha256 -days "$days" -in "$out/request.csr" -out "$out/cert.pem" \
    -extfile <(printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n') \
    >"$out/issue.log" 2>&1 || die "openssl ca failed to issue $out/cert.pem: $(cat "$out/issue.log")"
  rm -f "$out/request.csr" "$out/issue.log"
  serial=$(serial_of "$out/cert.pem")
  security permissions --role "$as" --certificate "$out/cert.pem" ${devs:+--devices "$devs"} --days "$days" \
    >"$out/permissions.xml"
  sign "$out/permissions.xml"
  echo "pki.sh: $out: $as '$(subject_of "$out/cert.pem")'${devs:+ for $devs} (serial $serial)" >&2
  earlier=$(records "$who" | awk -F'\t' -v s="$serial" '$1 == "valid" && $2 != s { printf "%s%s (until %s)", sep, $2, $3; sep = ", " }')
  if [ -n "$earlier" ]; then
    echo "pki.sh: warning: $who was issued before and its earlier certificate(s) stay valid until revoked: serial $earlier; revoke each with: pki.sh revoke --dir $dir --serial SERIAL" >&2
  fi
}

case "$cmd" in
  init)
    [ -n "$config" ] || die "--config LINE.yaml is required"
    mkdir -p "$dir/ca" "$cadir"
    chmod 700 "$cadir"
    new_ca identity_ca "identity CA"
    new_ca permissions_ca "permissions CA"
    [ -f "$dir/ca/identity_crl.pem" ] || crl
    security governance >"$dir/governance.xml"
    sign "$dir/governance.xml"
    issue bridge bridge
    abs=$(cd "$dir" && pwd)
    # What goes under the line file's dds: (a line file has one), indented as it goes there.
    cat <<EOF
  # dds.security: paste these lines, as they are, below the line file's dds: line
  security:
    identity_ca: $abs/ca/identity_ca.pem
    permissions_ca: $abs/ca/permissions_ca.pem
    governance: $abs/governance.p7s
    certificate: $abs/bridge/cert.pem
    private_key: $abs/bridge/key.pem
    permissions: $abs/bridge/permissions.p7s
    identity_crl: $abs/ca/identity_crl.pem
EOF
    echo "pki.sh: the CA keys are in $cadir: take that folder offline (issue, list, sign and revoke need it)" >&2
    ;;
  issue)
    [ -n "$config" ] || die "--config LINE.yaml is required"
    [ -n "$name" ] || die "--name is required"
    [ -n "$role" ] || die "--role is required"
    issue "$name" "$role" "$devices"
    ;;
  list)
    [ -f "$index" ] || die "no records in $cadir: give the folder with --ca-dir"
    printf 'status\tserial\tnot after (UTC)\tsubject\n'
    records "$name"
    ;;
  sign)
    ((${#files[@]})) || die "sign: which XML file?"
    for f in "${files[@]}"; do
      [[ $f == *.xml ]] || die "sign: $f is not a .xml file"
      sign "$f"
      echo "pki.sh: signed ${f%.xml}.p7s" >&2
    done
    ;;
  revoke)
    [ -f "$dir/ca/identity_ca.pem" ] || die "$dir has no CAs: run pki.sh init first"
    [ -f "$cadir/identity_ca.key" ] || die "no CA key in $cadir: give the folder with --ca-dir"
    ca_config
    # Everything is looked up before anything is revoked: a wrong serial or name changes nothing.
    targets=()
    for s in "${serials[@]}"; do
      want=$(norm_serial "$s") found=""
      while IFS=$'\t' read -r status serial _; do
        [ "$(norm_serial "$serial")" = "$want" ] || continue
        found=$serial
        [ "$status" != revoked ] || die "revoke: serial $serial is revoked already"
      done < <(records)
      [ -n "$found" ] || die "revoke: no certificate with serial $s in the records ($index; pki.sh list shows them)"
      [ -f "$issued/$found.pem" ] || die "revoke: serial $found is recorded but its copy $issued/$found.pem is missing: revoke it from its file"
      targets+=("$issued/$found.pem")
    done
    if [ -n "$name" ]; then
      record "$dir/$name/cert.pem"
      of_name=()
      while IFS=$'\t' read -r status serial _; do
        [ "$status" = revoked ] || of_name+=("$issued/$serial.pem")
      done < <(records "$name")
      if ((${#of_name[@]} == 0)); then
        records "$name" | grep . >/dev/null || die "revoke: no certificate of $name in the records ($index) nor $dir/$name/cert.pem"
        echo "pki.sh: $name: no certificate left to revoke (each one is revoked already)" >&2
      fi
      for f in "${of_name[@]}"; do [ -f "$f" ] || die "revoke: $f (a certificate of $name) is missing"; done
      targets+=("${of_name[@]}")
    fi
    for f in "${files[@]}"; do [ -f "$f" ] || die "revoke: no certificate $f"; done
    declare -A done_serials=()
    for f in "${targets[@]}" "${files[@]}"; do
      s=$(serial_of "$f")
      [ -z "${done_serials[$s]:-}" ] || continue  # named twice (by serial and by name)
      done_serials[$s]=1
      revoke_file "$f"
    done
    [ -z "$name" ] || echo "pki.sh: revoked ${#of_name[@]} certificate(s) of $name" >&2
    crl
    ;;
  *) usage ;;
esac
