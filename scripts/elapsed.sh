# Sourced by the set-up scripts: elapsed_since START prints the seconds since START ($SECONDS then) as "12 s" or
# "2 min 05 s", for their lines per phase.
elapsed_since() {
  local seconds=$((SECONDS - $1))
  if [ "$seconds" -ge 60 ]; then
    printf '%d min %02d s' $((seconds / 60)) $((seconds % 60))
  else
    printf '%d s' "$seconds"
  fi
}
