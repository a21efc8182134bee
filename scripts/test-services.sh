#!/usr/bin/env bash
# The system programs and the database server that the test suite needs beyond Python and Node:
#   chromium    the browser tests (tests/web/test_browser.py, Playwright drives Debian's build)
#   espeak-ng   the speech test (tests/web/test_speech.py)
#   postgresql  the web site's database tests on PostgreSQL (tests/web, TOURBOT_TEST_DATABASE_URL)
#   redis-server the fan-out tests (tests/web/test_fanout.py start their own broker on loopback)
#
# Installs what is missing when run as root on a machine with apt-get (as CI is), starts a
# PostgreSQL cluster on loopback with a `tourbot` role and a `tourbot_test` database, and prints the
# database URL as its only line on standard output (the Makefile exports it for pytest). Otherwise
# it fails, naming the one command that installs what is missing. Everything else goes to stderr.
#
# A database of your own is used as it is: set TOURBOT_TEST_DATABASE_URL before `make test`.
set -euo pipefail

PACKAGES=(chromium postgresql espeak-ng redis-server)
URL_DEFAULT="postgresql+psycopg://tourbot:tourbot@127.0.0.1:5432/tourbot_test"

say() { echo "test-services: $*" >&2; }

missing=()
[[ -x /usr/bin/chromium ]] || missing+=(chromium)
command -v redis-server >/dev/null 2>&1 || missing+=(redis-server)
command -v espeak-ng >/dev/null 2>&1 || missing+=(espeak-ng)
if [[ -z "${TOURBOT_TEST_DATABASE_URL:-}" ]] && ! command -v pg_ctlcluster >/dev/null 2>&1; then
  missing+=(postgresql)
fi

if ((${#missing[@]})); then
  if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null 2>&1; then
    say "installing ${missing[*]} (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get -o DPkg::Lock::Timeout=600 update -qq >&2
    apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    say "missing ${missing[*]}; install them with:"
    say "    sudo apt-get install -y --no-install-recommends ${PACKAGES[*]}"
    say "(then run make test again; \`make test-fast\` runs the tests that need none of them)"
    exit 1
  fi
fi

if [[ -n "${TOURBOT_TEST_DATABASE_URL:-}" ]]; then
  say "using TOURBOT_TEST_DATABASE_URL as set"
  echo "$TOURBOT_TEST_DATABASE_URL"
  exit 0
fi

# Already started (by an earlier run as root, or by hand): use it.
if PGPASSWORD=tourbot psql -qtAX -h 127.0.0.1 -p 5432 -U tourbot -d tourbot_test -c "SELECT 1" >/dev/null 2>&1; then
  echo "$URL_DEFAULT"
  exit 0
fi

if [[ $(id -u) -ne 0 ]]; then
  say "PostgreSQL is installed but this user cannot start its cluster; start it and create the"
  say "test database with:"
  say "    sudo bash scripts/test-services.sh"
  exit 1
fi

# Debian's cluster: create one if the package left none, start it, then the role and the database.
version=$(ls /etc/postgresql 2>/dev/null | sort -V | tail -n 1)
if [[ -z "$version" ]]; then
  version=$(ls /usr/lib/postgresql | sort -V | tail -n 1)
  pg_createcluster "$version" main >&2
fi
if ! pg_ctlcluster "$version" main status >/dev/null 2>&1; then
  say "starting PostgreSQL $version"
  pg_ctlcluster "$version" main start >&2
fi
psql_as_postgres() { su postgres -c "psql -qtAX -c \"$1\""; }
if [[ $(psql_as_postgres "SELECT 1 FROM pg_roles WHERE rolname='tourbot'") != 1 ]]; then
  psql_as_postgres "CREATE ROLE tourbot LOGIN SUPERUSER PASSWORD 'tourbot'" >&2
fi
if [[ $(psql_as_postgres "SELECT 1 FROM pg_database WHERE datname='tourbot_test'") != 1 ]]; then
  su postgres -c "createdb -O tourbot tourbot_test" >&2
fi
echo "$URL_DEFAULT"
