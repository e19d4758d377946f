#!/usr/bin/env bash
# The DDS Security material of a line, with openssl: two CAs, the signed governance, and signed
# identities (certificate, key, permissions) per role. README "Security" explains the whole.
#
#   launch_scripts/pki.sh init  --config LINE.yaml --dir DIR [--org NAME] [--days N]
#       DIR/ca/                 identity CA and permissions CA (certificate + key: keep the keys offline)
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
#
# ECDSA P-256 keys, SHA-256 signatures (what Fast DDS 2.9 accepts), subjects CN=<name>,O=<org>.
# linebridge-security (built with the bridge) writes the XML from the line file; LINEBRIDGE_BIN
# names its folder (default: build/bridge/app, or where PATH finds it, as the package installs it).
set -euo pipefail

usage() { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
die() { echo "pki.sh: $*" >&2; exit 2; }

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -ge 1 ] || usage
cmd=$1; shift
[[ $cmd =~ ^(init|issue|sign)$ ]] || usage
config="" dir="" org="linebridge" days=365 name="" role="" devices=""
files=()
while (($#)); do
  case "$1" in
    --config) config=${2:?}; shift ;;
    --dir) dir=${2:?}; shift ;;
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
    -signer "$dir/ca/permissions_ca.pem" -inkey "$dir/ca/permissions_ca.key"
}

new_ca() {  # NAME CN
  local base="$dir/ca/$1"
  [ -f "$base.pem" ] && { echo "pki.sh: keeping $base.pem" >&2; return; }
  openssl req -x509 -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 -days $((days * 10)) \
    -keyout "$base.key" -out "$base.pem" -subj "/O=$org/CN=$2" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" 2>/dev/null
  chmod 600 "$base.key"
}

issue() {  # NAME ROLE [DEVICES]
  local who=$1 as=$2 devs=${3:-} out="$dir/$1"
  [[ $who =~ ^[A-Za-z0-9_-]+$ ]] || die "--name: letters, digits, '_' and '-' only"
  [ -f "$dir/ca/identity_ca.pem" ] || die "$dir has no CAs: run pki.sh init first"
  mkdir -p "$out"
  openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 \
    -keyout "$out/key.pem" -out "$out/request.csr" -subj "/O=$org/CN=$who" 2>/dev/null
  chmod 600 "$out/key.pem"
  openssl x509 -req -in "$out/request.csr" -CA "$dir/ca/identity_ca.pem" -CAkey "$dir/ca/identity_ca.key" \
    -CAserial "$dir/ca/identity_ca.srl" -CAcreateserial -days "$days" -sha256 -out "$out/cert.pem" \
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
    mkdir -p "$dir/ca"
    chmod 700 "$dir/ca"
    new_ca identity_ca "identity CA"
    new_ca permissions_ca "permissions CA"
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
EOF
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
  *) usage ;;
esac
