# Sourced by the scripts that read test models (not run by itself). A model file
# is looked up in $MESHSTREAM_MODELS (when set), then tests/data (the small
# fixtures in the repository), then the cache scripts/fetch-models fills
# ($MESHSTREAM_MODEL_CACHE, default ${XDG_CACHE_HOME:-$HOME/.cache}/meshstream/models).
# tests/support/ms_test.c (ms_test_model_path) looks in the same places.

model_cache_dir() {
  echo "${MESHSTREAM_MODEL_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/meshstream/models}"
}

# Prints the path of model FILE, or one line on stderr naming the command that
# fetches it and returns 1.
model_path() {
  local file=$1 dir root
  root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
  for dir in ${MESHSTREAM_MODELS:+"$MESHSTREAM_MODELS"} "$root/tests/data" "$(model_cache_dir)"; do
    if [ -f "$dir/$file" ]; then echo "$dir/$file"; return 0; fi
  done
  echo "model $file not found: run scripts/fetch-models" >&2
  return 1
}
