#!/usr/bin/env bash
# The DDS Security material of a line, with openssl: two CAs, the signed governance, and signed
# identities (certificate, key, permissions) per role. README "Security" explains the whole.
#
#   launch_scripts/pki.sh init  --config LINE.yaml --dir DIR [--ca-dir CADIR] [--org NAME] [--days N]
#       DIR/ca/                 identity CA and permissions CA certificates, identity_crl.pem (no key)
#       CADIR (DIR/ca-private/) the CA keys and the CA's records: take it offline, the bridge never
#                               needs it (linebridge warns of a CA key beside the identity in use)
#       DIR/governance.p7s      the domain's governance, signed (governance.xml: what was signed)
#       DIR/bridge/             the bridge's identity: cert.pem key.pem permissions.p7s
#       and prints the dds.security block for the line file.
#   launch_scripts/pki.sh issue --config LINE.yaml --dir DIR --name NAME --role ROLE [--devices D1,D2] [--days N]
#       DIR/NAME/               cert.pem key.pem permissions.p7s (permissions.xml: what was signed)
#       ROLE: observer (reads status, events, info, diagnostics), operator (also set values and
#       momentary/feeder commands of --devices, required), engineer (also NMT, SDO, parameters,
#       feeder configuration; of --devices, default every device), bridge.
#   launch_scripts/pki.sh sign  --dir DIR FILE.xml
#       signs a governance or permissions document you edited by hand -> FILE.p7s
#   launch_scripts/pki.sh revoke --dir DIR [--name NAME] [CERT.pem...] [--days N]
#       revokes DIR/NAME/cert.pem (and any CERT.pem) and re-issues DIR/ca/identity_crl.pem, valid
#       N days; without a name it only re-issues the list (do that before its next update passes).
#       Takes effect when the bridge (and each client) restarts: a running participant keeps the
#       list it read at start.
# issue, sign and revoke take --ca-dir too (default DIR/ca-private, or DIR/ca where an older
# pki.sh left the keys).
#
# ECDSA P-256 keys, SHA-256 signatures (what Fast DDS 2.9 accepts), subjects CN=<name>,O=<org>.
# linebridge-security (built with the bridge) writes the XML from the line file; LINEBRIDGE_BIN
# names its folder (default: build/bridge/app, or where PATH finds it, as the package installs it).
set -euo pipefail

usage() { sed -n '2,30p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
die() { echo "pki.sh: $*" >&2; exit 2; }

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -ge 1 ] || usage
cmd=$1; shift
[[ $cmd =~ ^(init|issue|sign|revoke)$ ]] || usage
config="" dir="" cadir="" org="linebridge" days=365 name="" role="" devices=""
files=()
while (($#)); do
  case "$1" in
    --config) config=${2:?}; shift ;;
    --dir) dir=${2:?}; shift ;;
    --ca-dir) cadir=${2:?}; shift ;;
    --org) org=${2:?}; shift ;;
    --days) days=${2:?}; shift ;;
    --name) name=${2:?}; shift ;;
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

# The identity CA's records for `openssl ca` (revocations, CRL numbers), beside its key.
ca_config() {
  [ -f "$cadir/identity_ca.index" ] || : >"$cadir/identity_ca.index"
  [ -f "$cadir/identity_ca.crlnumber" ] || echo 01 >"$cadir/identity_ca.crlnumber"
  printf '[ca]\ndefault_ca = lb\n[lb]\ndatabase = %s\ncrlnumber = %s\ndefault_md = sha256\ndefault_crl_days = %s\nunique_subject = no\n' \
    "$cadir/identity_ca.index" "$cadir/identity_ca.crlnumber" "$days" >"$cadir/identity_ca.cnf"
}

crl() {  # re-issues DIR/ca/identity_crl.pem from the records, valid --days
  ca_config
  openssl ca -batch -config "$cadir/identity_ca.cnf" -gencrl -keyfile "$cadir/identity_ca.key" \
    -cert "$dir/ca/identity_ca.pem" -out "$dir/ca/identity_crl.pem" 2>/dev/null || die "openssl ca -gencrl failed"
  echo "pki.sh: $dir/ca/identity_crl.pem: next update $(openssl crl -noout -nextupdate -in "$dir/ca/identity_crl.pem" | sed 's/^nextUpdate=//')" >&2
}

revoke() {  # CERT.pem
  local cert=$1 serial
  [ -f "$cert" ] || die "revoke: no certificate $cert"
  ca_config
  openssl ca -batch -config "$cadir/identity_ca.cnf" -keyfile "$cadir/identity_ca.key" -cert "$dir/ca/identity_ca.pem" \
    -revoke "$cert" 2>&1 | grep -v '^Using configuration' >&2 || true
  serial=$(openssl x509 -noout -serial -in "$cert" | sed 's/^serial=//')
  grep -q "^R.*	$serial	" "$cadir/identity_ca.index" ||
    die "revoke: $cert is not in the revocation records (not issued by $dir/ca/identity_ca.pem?)"
  echo "pki.sh: revoked $cert '$(openssl x509 -noout -subject -nameopt RFC2253 -in "$cert" | sed 's/^subject=//')' (serial $serial)" >&2
}

issue() {  # NAME ROLE [DEVICES]
  local who=$1 as=$2 devs=${3:-} out="$dir/$1"
  [[ $who =~ ^[A-Za-z0-9_-]+$ ]] || die "--name: letters, digits, '_' and '-' only"
  [ -f "$dir/ca/identity_ca.pem" ] || die "$dir has no CAs: run pki.sh init first"
  [ -f "$cadir/identity_ca.key" ] || die "no CA key in $cadir: give the folder with --ca-dir"
  mkdir -p "$out"
  openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 \
    -keyout "$out/key.pem" -out "$out/request.csr" -subj "/O=$org/CN=$who" 2>/dev/null
  chmod 600 "$out/key.pem"
  openssl x509 -req -in "$out/request.csr" -CA "$dir/ca/identity_ca.pem" -CAkey "$cadir/identity_ca.key" \
    -CAserial "$cadir/identity_ca.srl" -CAcreateserial -days "$days" -sha256 -out "$out/cert.pem" \
    -extfile <(printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n') 2>/dev/null
  rm -f "$out/request.csr"
  security permissions --role "$as" --certificate "$out/cert.pem" ${devs:+--devices "$devs"} --days "$days" \
    >"$out/permissions.xml"
  sign "$out/permissions.xml"
  echo "pki.sh: $out: $as '$(openssl x509 -noout -subject -nameopt RFC2253 -in "$out/cert.pem" | sed 's/^subject=//')'${devs:+ for $devs}" >&2
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
    cat <<EOF
# dds.security for the line file (relative paths are taken from the line file's folder):
dds:
  security:
    identity_ca: $abs/ca/identity_ca.pem
    permissions_ca: $abs/ca/permissions_ca.pem
    governance: $abs/governance.p7s
    certificate: $abs/bridge/cert.pem
    private_key: $abs/bridge/key.pem
    permissions: $abs/bridge/permissions.p7s
    identity_crl: $abs/ca/identity_crl.pem
EOF
    echo "pki.sh: the CA keys are in $cadir: take that folder offline (issue, sign and revoke need it)" >&2
    ;;
  issue)
    [ -n "$config" ] || die "--config LINE.yaml is required"
    [ -n "$name" ] || die "--name is required"
    [ -n "$role" ] || die "--role is required"
    issue "$name" "$role" "$devices"
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
    [ -z "$name" ] || files+=("$dir/$name/cert.pem")
    for f in "${files[@]}"; do revoke "$f"; done
    crl
    ;;
  *) usage ;;
esac
