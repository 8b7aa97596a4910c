# Sourced first thing by the scripts in this folder, which take no arguments
# (their knobs are environment variables, named in each header):
#   . "$(dirname "$0")/script-usage.sh"; script_usage "$0" "$@"
# `-h` / `--help` prints the calling script's header comment and exits 0; any
# other argument is refused with one line on stderr and exit status 2.
script_usage() {
  local me=$1 name
  name=$(basename "$1")
  shift
  case "${1:-}" in
    "") return 0 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$me"; exit 0 ;;
    *) echo "$name: unknown argument '$1' (it takes none; try '$name --help')" >&2; exit 2 ;;
  esac
}
