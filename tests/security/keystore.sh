#!/usr/bin/env bash
# An SROS2 keystore made with openssl, in the layout `ros2 security create_keystore` and
# `create_enclave` write (ROS 2 Jazzy's sros2): one CA, EC prime256v1, that is both the
# identity CA and the permissions CA; keys in PKCS#8 PEM, as sros2 writes them; governance
# and permissions signed with S/MIME.
#
#   keystore.sh init KEYSTORE
#       the CA (public/ca.cert.pem, private/ca.key.pem, with the identity_ca.* and
#       permissions_ca.* names beside them) and enclaves/governance.{xml,p7s}: no
#       unauthenticated participants, discovery, liveliness and data encrypted, access
#       control on every topic (sros2's default governance).
#   keystore.sh enclave KEYSTORE NAME [--deny TOPIC]... [--expired] [--ca OTHER_KEYSTORE]
#       enclaves/NAME/: key.pem, cert.pem (CN=NAME), the two CA certificates,
#       governance.p7s, permissions.{xml,p7s} allowing every topic and partition on every
#       domain, after a deny rule for each TOPIC (a DDS topic name, rt/...). --expired: a
#       certificate valid in 2020 only. --ca: certificate issued by OTHER_KEYSTORE's CA.
#
# Every run makes new keys: a test makes its keystore fresh, in its own temporary directory.
set -euo pipefail

die() { echo "keystore.sh: $*" >&2; exit 2; }
[ $# -ge 2 ] || die "usage: keystore.sh init KEYSTORE | keystore.sh enclave KEYSTORE NAME [--deny TOPIC]... [--expired] [--ca OTHER]"
cmd=$1 ks=$2
shift 2

# Quiet openssl: its output goes to stderr only when it fails.
ossl() {
    local out
    if ! out=$(openssl "$@" 2>&1); then
        echo "openssl $1: $out" >&2
        exit 1
    fi
}

sign() { # FILE.xml -> FILE.p7s, signed by the permissions CA of keystore $1
    ossl smime -sign -text -in "$2" -out "${2%.xml}.p7s" -signer "$1/public/permissions_ca.cert.pem" \
        -inkey "$1/private/permissions_ca.key.pem"
}

# An `openssl ca` of the keystore $1, for certificates with given dates.
ca_config() {
    local dir=$1/private/ca
    mkdir -p "$dir"
    [ -f "$dir/index.txt" ] || : >"$dir/index.txt"
    [ -f "$dir/serial" ] || echo 1000 >"$dir/serial"
    cat >"$dir/ca.cnf" <<CNF
[ ca ]
default_ca = ca_default
[ ca_default ]
dir = $dir
database = $dir/index.txt
new_certs_dir = $dir
serial = $dir/serial
default_md = sha256
policy = any
unique_subject = no
copy_extensions = none
[ any ]
commonName = supplied
CNF
    echo "$dir/ca.cnf"
}

case $cmd in
init)
    mkdir -p "$ks/public" "$ks/private" "$ks/enclaves"
    ossl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$ks/private/ca.key.pem"
    ossl req -new -x509 -key "$ks/private/ca.key.pem" -out "$ks/public/ca.cert.pem" -days 3650 -sha256 \
        -subj "/CN=sros2testCA"
    for n in identity_ca permissions_ca; do
        ln -sf ca.cert.pem "$ks/public/$n.cert.pem"
        ln -sf ca.key.pem "$ks/private/$n.key.pem"
    done
    cat >"$ks/enclaves/governance.xml" <<'XML'
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>230</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
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
XML
    sign "$ks" "$ks/enclaves/governance.xml"
    ;;
enclave)
    [ $# -ge 1 ] || die "enclave: give its NAME"
    name=$1
    shift
    deny=() expired=0 ca=$ks
    while [ $# -gt 0 ]; do
        case $1 in
        --deny) deny+=("$2"); shift 2 ;;
        --expired) expired=1; shift ;;
        --ca) ca=$2; shift 2 ;;
        *) die "enclave: unknown option $1" ;;
        esac
    done
    case $name in /*) ;; *) die "an enclave name is absolute: $name" ;; esac
    dir=$ks/enclaves${name}
    mkdir -p "$dir"
    ossl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$dir/key.pem"
    ossl req -new -key "$dir/key.pem" -out "$dir/req.csr" -subj "/CN=${name//\//\\/}"
    if [ $expired = 1 ]; then
        dates=(-startdate 20200101000000Z -enddate 20201231000000Z)
    else
        dates=(-days 3650)
    fi
    ossl ca -batch -notext -config "$(ca_config "$ca")" -cert "$ca/public/identity_ca.cert.pem" \
        -keyfile "$ca/private/identity_ca.key.pem" -in "$dir/req.csr" -out "$dir/cert.pem" "${dates[@]}"
    rm "$dir/req.csr"
    cp "$ks/public/identity_ca.cert.pem" "$dir/identity_ca.cert.pem"
    cp "$ks/public/permissions_ca.cert.pem" "$dir/permissions_ca.cert.pem"
    cp "$ks/enclaves/governance.p7s" "$dir/governance.p7s"
    rules=""
    for t in "${deny[@]+"${deny[@]}"}"; do
        rules+="
      <deny_rule>
        <domains><id_range><min>0</min><max>230</max></id_range></domains>
        <publish><topics><topic>$t</topic></topics></publish>
        <subscribe><topics><topic>$t</topic></topics></subscribe>
      </deny_rule>"
    done
    cat >"$dir/permissions.xml" <<XML
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="$name">
      <subject_name>CN=$name</subject_name>
      <validity><not_before>2020-01-01T00:00:00</not_before><not_after>2035-01-01T00:00:00</not_after></validity>$rules
      <allow_rule>
        <domains><id_range><min>0</min><max>230</max></id_range></domains>
        <publish><topics><topic>*</topic></topics><partitions><partition>*</partition></partitions></publish>
        <subscribe><topics><topic>*</topic></topics><partitions><partition>*</partition></partitions></subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
XML
    sign "$ks" "$dir/permissions.xml"
    ;;
*) die "unknown command $cmd (init or enclave)" ;;
esac
