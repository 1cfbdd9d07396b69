# The address a server started on port 0 announces on its standard output: lipsyncd prints
# "lipsyncd listening on HOST:PORT" (server/src/main.cpp), the bare gRPC server of the benchmarks
# "listening on HOST:PORT" (tests/bench/grpc_baseline_server.cpp). Sourced by the scripts that start
# one with its standard output in a file:
#
#   source "$root/tests/support/listening_address.sh"
#   lipsyncd --listen 127.0.0.1:0 >"$out" 2>"$err" &
#   address=$(wait_for_listening_address "$out" 10 $!) || { echo "lipsyncd did not start"; exit 1; }
#
# The same line is read by tests/support/listening_address.py in Python and by
# wait_for_listening_address in tests/support/child_process.hpp in C++.

# listening_address FILE: prints HOST:PORT from the first line of FILE that starts with
# "lipsyncd listening on " or "listening on "; status 1, printing nothing, when there is none.
listening_address() {
  local line
  line=$(grep -m 1 -E '^(lipsyncd )?listening on [^ ]' "$1" 2>/dev/null) || return 1
  line=${line#lipsyncd }
  line=${line#listening on }
  printf '%s\n' "${line%% *}"
}

# wait_for_listening_address FILE TIMEOUT_S [PID]: what listening_address prints, once FILE has
# that line (looked for every 0.1 s); status 1, printing nothing, when it has not come within
# TIMEOUT_S seconds, or when the process PID (if given) has ended without printing it.
wait_for_listening_address() {
  local file=$1 timeout_s=$2 pid=${3:-} try
  for ((try = 0; try < timeout_s * 10; ++try)); do
    listening_address "$file" && return 0
    if [[ -n $pid ]] && ! kill -0 "$pid" 2>/dev/null; then break; fi
    sleep 0.1
  done
  listening_address "$file"
}
