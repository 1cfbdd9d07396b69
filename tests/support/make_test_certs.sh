#!/bin/bash
# Certificates for the TLS tests, made with openssl at test time (nothing is
# committed): make_test_certs.sh DIR writes into DIR
#   ca.pem                       a test CA (ca.key its key)
#   server.pem server.key        a server certificate for localhost and 127.0.0.1, signed by ca
#   server2.pem server2.key      a second one (CN lipsyncd-reloaded), for reload tests
#   client.pem client.key        a client certificate signed by ca
#   other-ca.pem                 an unrelated CA (other-ca.key)
#   other-client.pem/.key        a client certificate signed by other-ca
#   other-server.pem/.key        a server certificate signed by other-ca
# EC P-256 keys: quick to make. Valid for 2 days.
set -euo pipefail
dir=${1:?usage: make_test_certs.sh DIR}
mkdir -p "$dir"
cd "$dir"

ca() {  # ca NAME
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 \
    -subj "/CN=lipsync test $1" -keyout "$1.key" -out "$1.pem" 2>/dev/null
}
leaf() {  # leaf NAME CA CN EXTENSIONS
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=$3" \
    -keyout "$1.key" -out "$1.csr" 2>/dev/null
  printf '%s\n' "$4" > "$1.ext"
  openssl x509 -req -in "$1.csr" -CA "$2.pem" -CAkey "$2.key" -CAcreateserial -days 2 \
    -extfile "$1.ext" -out "$1.pem" 2>/dev/null
  rm -f "$1.csr" "$1.ext"
}
server_ext='subjectAltName=DNS:localhost,IP:127.0.0.1
extendedKeyUsage=serverAuth'
client_ext='extendedKeyUsage=clientAuth'

ca ca
ca other-ca
leaf server ca lipsyncd "$server_ext"
leaf server2 ca lipsyncd-reloaded "$server_ext"
leaf client ca lipsync-client "$client_ext"
leaf other-client other-ca lipsync-intruder "$client_ext"
leaf other-server other-ca lipsyncd-impostor "$server_ext"
