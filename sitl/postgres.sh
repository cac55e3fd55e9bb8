#!/usr/bin/env bash
# A local PostgreSQL server for the ledger's tests (a team's shared ledger, `--ledger
# postgres://...`): installs Debian's postgresql if its tools are absent, creates and starts a
# cluster, makes the role and the database, waits until it answers, and prints its URL on stdout
# (the value of EMPLAN_TEST_POSTGRES). A second run finds the server up and prints the same URL.
#
# usage: sitl/postgres.sh
# PG_PORT (5432), PG_USER (emplan), PG_PASSWORD (emplan) and PG_DB (emplan_test) change them.
# Runs as root (CI) or as a user who may `sudo -u postgres`.
set -euo pipefail
port=${PG_PORT:-5432}
user=${PG_USER:-emplan}
password=${PG_PASSWORD:-emplan}
db=${PG_DB:-emplan_test}

if [ "$(id -u)" = 0 ]; then
  as_root() { "$@"; }
  as_postgres() { runuser -u postgres -- "$@"; }
else
  as_root() { sudo "$@"; }
  as_postgres() { sudo -u postgres "$@"; }
fi

if ! command -v pg_ctlcluster >/dev/null 2>&1 || ! command -v pg_lsclusters >/dev/null 2>&1; then
  echo "postgres.sh: installing Debian's postgresql" >&2
  as_root apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq postgresql >&2
fi

# The newest installed server version.
version=$(find /usr/lib/postgresql -mindepth 1 -maxdepth 1 -printf '%f\n' | sort -n | tail -1)
if [ -z "$version" ]; then
  echo "postgres.sh: no server under /usr/lib/postgresql after installing postgresql" >&2
  exit 1
fi

# The cluster on our port: the package's own (`main`) if it listens there, else one we make.
cluster=$(pg_lsclusters -h | awk -v v="$version" -v p="$port" '$1 == v && $3 == p { print $2; exit }')
if [ -z "$cluster" ]; then
  cluster=emplan
  echo "postgres.sh: creating cluster $version/$cluster on port $port" >&2
  as_root pg_createcluster --port "$port" "$version" "$cluster" >&2
fi
status=$(pg_lsclusters -h | awk -v v="$version" -v c="$cluster" '$1 == v && $2 == c { print $4 }')
if [ "$status" != online ]; then
  echo "postgres.sh: starting cluster $version/$cluster" >&2
  as_root pg_ctlcluster "$version" "$cluster" start >&2
fi

for _ in $(seq 1 60); do
  if pg_isready -q -h 127.0.0.1 -p "$port"; then
    break
  fi
  sleep 0.5
done
if ! pg_isready -q -h 127.0.0.1 -p "$port"; then
  echo "postgres.sh: the server on 127.0.0.1:$port does not answer (pg_isready)" >&2
  exit 1
fi

psql_pg() { as_postgres psql -p "$port" -v ON_ERROR_STOP=1 -qtA "$@"; }
if [ "$(psql_pg -c "SELECT 1 FROM pg_roles WHERE rolname = '$user'")" != 1 ]; then
  psql_pg -c "CREATE ROLE \"$user\" LOGIN PASSWORD '$password'" >&2
else
  psql_pg -c "ALTER ROLE \"$user\" LOGIN PASSWORD '$password'" >&2
fi
if [ "$(psql_pg -c "SELECT 1 FROM pg_database WHERE datname = '$db'")" != 1 ]; then
  psql_pg -c "CREATE DATABASE \"$db\" OWNER \"$user\"" >&2
fi

echo "postgres://$user:$password@127.0.0.1:$port/$db"
