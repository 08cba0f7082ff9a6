# Sourced by the measuring scripts: mine one field with the default detector and with the
# paper's preset (the baseline every table shows beside it), skipping finished libraries.
#
#   mine_presets BIN FIELD GT LIB PAPER_LIB LOG LABEL [MORE_FLAGS...]
#
# LIB and PAPER_LIB receive the libraries (with metrics.json against GT); LOG.mine.log and
# LOG.mine_paper.log the output; MORE_FLAGS go to the default-preset run only. A failure
# is reported with LABEL and does not stop the calling script.
mine_presets() {
  local bin=$1 field=$2 gt=$3 lib=$4 paper=$5 log=$6 label=$7
  shift 7
  [ -f "$lib/metrics.json" ] ||
    "$bin" mine "$field" --out "$lib" --gt "$gt" --force "$@" > "$log.mine.log" 2>&1 ||
    echo "== $label: mining failed (see $log.mine.log)"
  [ -f "$paper/metrics.json" ] ||
    "$bin" mine "$field" --out "$paper" --gt "$gt" --force --preset paper \
      > "$log.mine_paper.log" 2>&1 ||
    echo "== $label: mining with --preset paper failed (see $log.mine_paper.log)"
}
