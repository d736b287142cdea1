# What the table scripts share; sourced after HERE is set.
TEXTURES=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures
PYTHON=/usr/bin/python3

floor_path() {  # floor_path NAME: what --floor takes
  case $1 in
    procedural) echo procedural ;;
    asphalt) echo "$TEXTURES/asphalt_02_2048.jpg" ;;
    brick) echo "$TEXTURES/brick_floor_1024.png" ;;
  esac
}

# table_case ROUTE:FLOOR: sets route, floor and floor_arg (what --floor takes); fails, saying
# so, when the floor is a texture that is missing.
table_case() {
  route=${1%%:*} floor=${1#*:}
  floor_arg=$(floor_path "$floor")
  if [ "$floor" != procedural ] && [ ! -f "$floor_arg" ]; then
    echo "$1: skipped, $floor_arg is missing"
    return 1
  fi
}

# aligned TUM GROUNDTRUTH_TUM: "rms max" of the positions after the best rigid alignment
aligned() { "$PYTHON" "$HERE/benchmarks/aligned.py" "$1" "$2"; }
