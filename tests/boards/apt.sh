# Sourced by the scripts that fetch Debian packages.
# shellcheck shell=bash

# `apt-get update` with the given command prefix (sudo, apt-get and its options), tried again after
# a pause: a Debian mirror in the middle of a sync serves index files of the wrong size for a
# minute or two, and that should not fail a CI run. If it still fails, apt keeps the lists it did
# fetch (and any older ones), so this goes on with a warning: a package that only a missing list
# holds then fails its install or download with apt's own message, naming it.
apt_update() {
    local try
    for try in 1 2 3 4; do
        "$@" update -qq && return 0
        if [ "$try" -lt 4 ]; then
            echo "apt-get update failed (try $try of 4); trying again in $((try * 30)) s" >&2
            sleep $((try * 30))
        fi
    done
    echo "apt-get update failed 4 times; going on with the package lists apt has" >&2
}
