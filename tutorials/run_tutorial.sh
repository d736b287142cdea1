# Runs a tutorial's run.sh in a scratch directory with mosaicloc on the PATH, after checking
# that the tutorial's README quotes every line of the script.
set -eu
tutorial=$1
bin_dir=$2
while IFS= read -r line; do
  case "$line" in ''|'#'*) continue ;; esac
  grep -qxF -- "$line" "$tutorial/README.md" || { echo "README.md does not quote: $line" >&2; exit 1; }
done < "$tutorial/run.sh"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
PATH="$bin_dir:$PATH" bash -eu "$tutorial/run.sh"
