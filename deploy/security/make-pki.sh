#!/usr/bin/env bash
# make-pki.sh: the DDS-Security PKI of one robot team (docs/security.md), with openssl only.
#
#   deploy/security/make-pki.sh OUT_DIR --agents 1 2 3 [--days 825] [--domains 0-232]
#   deploy/security/make-pki.sh OUT_DIR --add-agent 4        (same CA, one more robot)
#   deploy/security/make-pki.sh OUT_DIR --revoke 2           (revoke robot 2's certificate)
#
# OUT_DIR/ca/            the team CA (ECDSA prime256v1): ca.key stays on the machine that
#                        issues certificates, never on a robot. The same CA signs identities
#                        and the governance/permissions documents (identity CA = permissions CA).
# OUT_DIR/governance.xml the domain rules (signed copy: governance.p7s in every participant dir)
# OUT_DIR/server/        OUT_DIR/agent_<id>/: what one participant needs, copy the directory to
#                        it and point `security_dir` (or --security-dir) at it:
#     identity_ca.pem  permissions_ca.pem  cert.pem  key.pem  governance.p7s  permissions.p7s
#     identity_crl.pem   (after the first --revoke: the CA's revocation list; copy it to every
#                        participant, the server at least; it expires after --days)
#
# Permissions: agent <id> may publish the agent topics (ccm/keyframes, ccm/map_points, the
# two update topics, ccm/agent_status) only in DDS partition agent_<id>, and read only
# ccm/server_to_agent in that partition. The server reads the agent topics in agent_* and
# writes ccm/server_to_agent in agent_*. The server also checks that the agent id inside each
# message matches the partition it came from (server_runtime/server_comm.cc).
set -euo pipefail

usage() {
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

[ $# -ge 1 ] || usage
OUT="$1"
shift
AGENTS=()
REVOKE=()
ADD_ONLY=0
DAYS=825
DOMAIN_MIN=0
DOMAIN_MAX=232
while [ $# -gt 0 ]; do
  case "$1" in
    --agents)
      shift
      while [ $# -gt 0 ] && [[ "$1" != --* ]]; do AGENTS+=("$1"); shift; done
      ;;
    --add-agent) ADD_ONLY=1; AGENTS+=("$2"); shift 2 ;;
    --revoke) REVOKE+=("$2"); shift 2 ;;
    --days) DAYS="$2"; shift 2 ;;
    --domains) DOMAIN_MIN="${2%-*}"; DOMAIN_MAX="${2#*-}"; shift 2 ;;
    -h|--help) usage ;;
    *) echo "make-pki.sh: unknown argument '$1'" >&2; usage ;;
  esac
done
[ ${#AGENTS[@]} -gt 0 ] || [ ${#REVOKE[@]} -gt 0 ] ||
  { echo "make-pki.sh: give at least one agent id (--agents 1 2 ...)" >&2; exit 2; }
for id in "${AGENTS[@]}" "${REVOKE[@]}"; do
  # Agent ids are 16 bits on the wire and 0 is never an agent (idl/ccm_msgs.idl).
  [[ "$id" =~ ^[0-9]+$ ]] && [ "$id" -ge 1 ] && [ "$id" -le 65535 ] ||
    { echo "make-pki.sh: agent id '$id' is not in 1..65535" >&2; exit 2; }
done
command -v openssl >/dev/null || { echo "make-pki.sh: openssl not found (apt install openssl)" >&2; exit 1; }

ORG="ccm-slam team"
CA="$OUT/ca"
umask 077  # keys readable by their owner only
mkdir -p "$CA"

# Revocation: mark the certificate revoked in the CA's database, issue a new CRL (valid for
# --days) and copy it into every participant directory. Fast DDS 2.9.1 checks it through
# dds.sec.auth.builtin.PKI-DH.identity_crl (set by the runtimes when identity_crl.pem exists).
if [ ${#REVOKE[@]} -gt 0 ]; then
  [ -f "$CA/ca.key" ] || { echo "make-pki.sh: --revoke needs the CA in $CA" >&2; exit 1; }
  touch "$CA/index.txt"
  [ -f "$CA/crlnumber" ] || echo 01 >"$CA/crlnumber"
  printf '[ ca ]\ndefault_ca = team\n[ team ]\ndatabase = %s\ncrlnumber = %s\ncertificate = %s\nprivate_key = %s\ndefault_md = sha256\ndefault_crl_days = %s\n' \
    "$CA/index.txt" "$CA/crlnumber" "$CA/ca.pem" "$CA/ca.key" "$DAYS" >"$CA/ca.cnf"
  for id in "${REVOKE[@]}"; do
    cert="$OUT/agent_$id/cert.pem"
    [ -f "$cert" ] || { echo "make-pki.sh: no certificate $cert to revoke" >&2; exit 1; }
    openssl ca -config "$CA/ca.cnf" -revoke "$cert" 2>/dev/null || { echo "make-pki.sh: revoking $cert failed" >&2; exit 1; }
    echo "[pki] revoked $cert"
  done
  openssl ca -config "$CA/ca.cnf" -gencrl -out "$CA/crl.pem" 2>/dev/null
  for dir in "$OUT"/server "$OUT"/agent_*; do
    if [ -d "$dir" ]; then cp "$CA/crl.pem" "$dir/identity_crl.pem"; fi
  done
  echo "[pki] $CA/crl.pem copied as identity_crl.pem into every participant directory: deploy it"
  [ ${#AGENTS[@]} -gt 0 ] || exit 0
fi

if [ "$ADD_ONLY" -eq 1 ]; then
  [ -f "$CA/ca.key" ] || { echo "make-pki.sh: --add-agent needs an existing CA in $CA" >&2; exit 1; }
else
  [ -f "$CA/ca.key" ] && { echo "make-pki.sh: $CA/ca.key exists; use --add-agent, or a new OUT_DIR" >&2; exit 1; }
  openssl ecparam -name prime256v1 -genkey -noout -out "$CA/ca.key"
  openssl req -new -x509 -key "$CA/ca.key" -sha256 -days "$DAYS" -subj "/O=$ORG/CN=ccm team CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" -out "$CA/ca.pem"
  echo 00 >"$CA/serial"  # (openssl x509 -CAserial)
fi

# Dates of the permissions' validity, in the format the DDS-Security spec uses.
NOT_BEFORE="$(date -u -d '-1 day' +%Y-%m-%dT%H:%M:%S)"
NOT_AFTER="$(date -u -d "+$DAYS days" +%Y-%m-%dT%H:%M:%S)"
DOMAINS="<domains><id_range><min>$DOMAIN_MIN</min><max>$DOMAIN_MAX</max></id_range></domains>"

sign() {  # S/MIME-signs $1 into $2 with the CA (the permissions CA)
  openssl smime -sign -in "$1" -text -out "$2" -signer "$CA/ca.pem" -inkey "$CA/ca.key"
}

# Governance: nobody unauthenticated joins; discovery, liveliness, submessages and payloads
# of every topic are encrypted and read/write access is checked against the permissions.
# RTPS-message protection stays NONE: payload + submessage encryption already hide the data
# and authenticate every submessage; a third (whole-message) layer would cost another
# AES-GCM pass per datagram for nothing the first two miss (only the RTPS header is plain).
if [ ! -f "$OUT/governance.xml" ]; then
  cat >"$OUT/governance.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <domain_access_rules>
    <domain_rule>
      $DOMAINS
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
  sign "$OUT/governance.xml" "$OUT/governance.p7s"
fi

AGENT_TOPICS="<topic>ccm/keyframes</topic><topic>ccm/map_points</topic><topic>ccm/keyframe_updates</topic><topic>ccm/map_point_updates</topic><topic>ccm/agent_status</topic>"

# issue NAME ROLE_OU CN GRANT_RULES: key, certificate and signed permissions of one participant.
issue() {
  local name="$1" ou="$2" cn="$3" rules="$4" dir="$OUT/$1"
  [ -f "$dir/cert.pem" ] && { echo "make-pki.sh: $dir exists; revoke/reissue it by hand (docs/security.md)" >&2; exit 1; }
  mkdir -p "$dir"
  openssl ecparam -name prime256v1 -genkey -noout -out "$dir/key.pem"
  openssl req -new -key "$dir/key.pem" -sha256 -subj "/O=$ORG/OU=$ou/CN=$cn" -out "$dir/cert.csr"
  printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n' >"$dir/ext.cnf"
  openssl x509 -req -in "$dir/cert.csr" -CA "$CA/ca.pem" -CAkey "$CA/ca.key" -CAserial "$CA/serial" -sha256 \
    -days "$DAYS" -extfile "$dir/ext.cnf" -out "$dir/cert.pem" 2>/dev/null
  rm -f "$dir/cert.csr" "$dir/ext.cnf"
  # The grant names the certificate's subject exactly as Fast DDS prints it (RFC 2253).
  local subject
  subject="$(openssl x509 -in "$dir/cert.pem" -noout -subject -nameopt RFC2253 | sed 's/^subject=//')"
  cat >"$dir/permissions.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <permissions>
    <grant name="$name">
      <subject_name>$subject</subject_name>
      <validity><not_before>$NOT_BEFORE</not_before><not_after>$NOT_AFTER</not_after></validity>
      <allow_rule>
        $DOMAINS
$rules
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  sign "$dir/permissions.xml" "$dir/permissions.p7s"
  cp "$CA/ca.pem" "$dir/identity_ca.pem"
  cp "$CA/ca.pem" "$dir/permissions_ca.pem"
  cp "$OUT/governance.p7s" "$dir/governance.p7s"
  if [ -f "$CA/crl.pem" ]; then cp "$CA/crl.pem" "$dir/identity_crl.pem"; fi
  echo "[pki] $dir: $subject"
}

if [ "$ADD_ONLY" -eq 0 ]; then
  issue server server ccm-server "        <publish><topics><topic>ccm/server_to_agent</topic></topics><partitions><partition>agent_*</partition></partitions></publish>
        <publish><topics><topic>ccm/server_status</topic></topics></publish>
        <subscribe><topics>$AGENT_TOPICS</topics><partitions><partition>agent_*</partition></partitions></subscribe>"
  # The operator's ccm_ctl: may only read the server's status.
  issue ctl operator ccm-ctl "        <subscribe><topics><topic>ccm/server_status</topic></topics></subscribe>"
fi
for id in "${AGENTS[@]}"; do
  issue "agent_$id" agent "ccm-agent-$id" "        <publish><topics>$AGENT_TOPICS</topics><partitions><partition>agent_$id</partition></partitions></publish>
        <subscribe><topics><topic>ccm/server_to_agent</topic></topics><partitions><partition>agent_$id</partition></partitions></subscribe>"
done
