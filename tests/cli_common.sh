# Helpers of the cli_*.sh tests (sourced).

# jelly_deck DT END_TIME CELL YOUNGS GEOMETRY [MODEL [SIMULATION]]: a deck of one [[geometry]]
# (GEOMETRY: its key lines) made of a jelly (nu 0.3, 1000 kg/m^3); ElastoGen's, or the MPM's
# when MODEL names an MPM law. SIMULATION: more [simulation] lines.
jelly_deck() {
  local dt=$1 end=$2 cell=$3 youngs=$4 geometry=$5 model=${6:-} simulation=${7:-}
  printf '[simulation]\ndt = %s\nend_time = %s\n' "$dt" "$end"
  [[ -n $simulation ]] && printf '%s\n' "$simulation"
  [[ -n $model ]] && printf '[solver]\nmethod = "mpm"\n'
  printf '[domain]\nvoxel_size = %s\n[[geometry]]\n%s\n[material]\n' "$cell" "$geometry"
  [[ -n $model ]] && printf 'model = "%s"\n' "$model"
  printf 'youngs_modulus = %s\npoisson_ratio = 0.3\ndensity = 1000\n' "$youngs"
}

# box LO HI: the key lines of a [[geometry]] box.
box() { printf 'type = "box"\nlo = %s\nhi = %s' "$1" "$2"; }

# region NAME LO HI [KEYS]: an [[NAME]] box region (fixed, force, ...); KEYS: more key lines.
region() {
  printf '[[%s]]\nlo = %s\nhi = %s\n' "$1" "$2" "$3"
  if [[ -n ${4:-} ]]; then printf '%s\n' "$4"; fi
}
