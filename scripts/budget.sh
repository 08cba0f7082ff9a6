# Sourced by the measuring scripts: turn a training budget into `assetfield train` flags.
#
#   budget_flags BUDGET   -> sets the array BUDGET_FLAGS and the string BUDGET_NAME
#
# BUDGET is `Nit` (N iterations of 4096 rays: the same field on every machine, however fast
# or busy; what the scripts that measure mining use), `Nmin` (N minutes of CPU time divided
# by the worker threads, `--clock cpu`: what time-to-quality figures use) or a bare number
# (minutes, as these scripts always took).
budget_flags() {
  case "$1" in
    *it) BUDGET_FLAGS=(--iters "${1%it}"); BUDGET_NAME="${1%it} iterations" ;;
    *min) BUDGET_FLAGS=(--minutes "${1%min}" --clock cpu); BUDGET_NAME="${1%min} CPU-minutes" ;;
    default) BUDGET_FLAGS=(); BUDGET_NAME="the default schedule (30000 iterations)" ;;
    ''|*[!0-9.]*) echo "budget '$1': give Nit (iterations), Nmin (CPU minutes) or default" >&2; exit 2 ;;
    *) BUDGET_FLAGS=(--minutes "$1" --clock cpu); BUDGET_NAME="$1 CPU-minutes" ;;
  esac
}
