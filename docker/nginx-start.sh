#!/bin/sh
# compose.yaml's nginx: names the container's DNS server as nginx's resolver, so that nginx can
# look the replicas' names up again while it runs (nginx.conf), then runs nginx in the
# foreground as the image does.
set -eu
server=$(awk '$1 == "nameserver" { print $2; exit }' /etc/resolv.conf)
[ -n "$server" ] || { echo "nginx-start.sh: no nameserver in /etc/resolv.conf" >&2; exit 1; }
case $server in *:*) server="[$server]" ;; esac
echo "resolver $server valid=5s ipv6=off;" > /etc/nginx/resolver.conf
exec nginx -p /etc/nginx/ -c /etc/nginx/nginx.conf -g 'daemon off;'
