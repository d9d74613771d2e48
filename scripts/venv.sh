# Sourced by scripts/fly.sh and scripts/test.sh: `ensure_venv SPEC` makes .venv hold mavreg
# installed as SPEC ('.' or '.[extra,...]', e.g. '.[test]'), installing only when needed, so
# that a machine once set up runs offline:
#   - no .venv/bin/python: create the environment, then install;
#   - pyproject.toml changed since the last install (its SHA-256 is kept, with each SPEC
#     installed, in .venv/.mavreg-installed), or an extra of SPEC was never installed from it:
#     install. ('.' is satisfied by any install from the same pyproject.toml.)
# Otherwise nothing is downloaded. MAVREG_REINSTALL=1 forces the install. To add an extra
# (e.g. gcs), change the SPEC passed by the calling script: '.[test,gcs]'.
# After an install MAVREG_INSTALLED_NOW is 1 (scripts/fly.sh then runs `mavreg warm-up`).
MAVREG_INSTALLED_NOW=0
ensure_venv() {
    local spec="$1" marker=.venv/.mavreg-installed hash line
    hash="$(python3 -c 'import hashlib, sys; print(hashlib.sha256(open(sys.argv[1], "rb").read()).hexdigest())' pyproject.toml)"
    line="$hash $spec"
    if [ ! -x .venv/bin/python ]; then
        python3 -m venv .venv
        .venv/bin/python -m pip install --quiet --upgrade pip
    elif [ "${MAVREG_REINSTALL:-0}" != 1 ] && _mavreg_installed "$hash" "$spec" "$marker"; then
        return 0
    fi
    .venv/bin/python -m pip install --quiet -e "$spec"
    MAVREG_INSTALLED_NOW=1
    # keep what was installed from this pyproject.toml (another SPEC may be there too)
    { grep -s "^$hash " "$marker" | grep -vxF -- "$line"; echo "$line"; } > "$marker.new" || true
    mv "$marker.new" "$marker"
}

# _mavreg_installed HASH SPEC MARKER: true when MARKER has an install from HASH and every
# extra of SPEC was installed from it.
_mavreg_installed() {
    local lines extra
    lines="$(grep -s "^$1 " "$3")" || return 1
    for extra in $(echo "$2" | sed -n 's/^\.\[\(.*\)\]$/\1/p' | tr ',' ' '); do
        echo "$lines" | cut -d' ' -f2- | sed -n 's/^\.\[\(.*\)\]$/\1/p' | tr ',' '\n' | grep -qxF -- "$extra" || return 1
    done
}
