# Sourced by tools/install.sh and tools/run-tests.sh: a step runs unless what it was run from
# (a digest of its inputs, kept in target/install-stamps/KEY) is what it would run from now.
# Callers set `who` (the script's name, for the messages).
stamps=target/install-stamps
mkdir -p "$stamps"

# The digest of a step's inputs: the files (their paths and bytes) and the tools' versions.
digest() {
  {
    find "$@" -type f -not -path '*/__pycache__/*' -not -name '*.pyc' -print0 | sort -z |
      xargs -0 sha256sum
    rustc --version 2>/dev/null || true
    python3 -c 'import sys; print(sys.executable, sys.version)'
    pwd
  } | sha256sum | cut -d' ' -f1
}

# Runs a step unless its stamp holds WANT; records it after the step succeeds.
#   step KEY "WHAT" WANT COMMAND...
step() {
  local key=$1 what=$2 want=$3 t=$SECONDS
  shift 3
  if [ "$(cat "$stamps/$key" 2>/dev/null)" = "$want" ]; then
    echo "$who: $what: skipped (installed from these inputs already)"
    return
  fi
  rm -f "$stamps/$key"
  "$@"
  echo "$want" >"$stamps/$key"
  echo "$who: $what: $((SECONDS - t)) s"
}

# Forgets a step's stamp (what it installed is gone or was replaced).
fresh() { rm -f "$stamps/$1"; }
