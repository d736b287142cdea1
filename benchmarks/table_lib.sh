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

# aligned TUM GROUNDTRUTH_TUM: "rms max" of the positions after the best rigid alignment
aligned() { "$PYTHON" "$HERE/benchmarks/aligned.py" "$1" "$2"; }
