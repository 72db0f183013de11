# Shared by scripts/test, scripts/dqo and scripts/demo: environment, dependencies, the build.
# Source it; it defines functions and variables only.

DQO_REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DQO_BUILD=${DQO_BUILD_DIR:-$DQO_REPO/.build}     # ignored by git
DQO_WS=$DQO_BUILD/ws                             # catkin workspace: src/dqo_map -> the repo
DQO_CORE=$DQO_BUILD/core                         # plain CMake build of the core (no ROS, no CUDA)
DQO_JOBS=${DQO_JOBS:-2}

# pyenv's python3 comes first on PATH and cannot import Debian's ROS modules: take it off PATH.
dqo_clean_path() {
  local out="" p
  IFS=: read -r -a parts <<< "$PATH"
  for p in "${parts[@]}"; do
    case "$p" in *pyenv*) continue ;; esac
    out="${out:+$out:}$p"
  done
  export PATH="$out"
  export ROS_HOME=${ROS_HOME:-$DQO_BUILD/ros_home}
  export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/ccache}
  export CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-5G}
  # Paths inside the repository enter ccache's hash relative to the build directory, so that a
  # second clone (another folder) hits the first one's cache.
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$DQO_REPO}
}

dqo_log() { printf '[dqo] %s\n' "$*" >&2; }

# Installs the apt packages of scripts/apt-packages.txt that are missing (the one list).
dqo_install_deps() {
  local want missing=()
  mapfile -t want < <(grep -v '^\s*#' "$DQO_REPO/scripts/apt-packages.txt" | awk 'NF {print $1}')
  for p in "${want[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    dqo_log "apt packages: all ${#want[@]} installed"
    return 0
  fi
  dqo_log "apt packages: installing ${#missing[@]} missing: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { dqo_log "not root and no sudo: install them by hand"; return 1; }
    sudo="sudo"
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q >/dev/null || { dqo_log "apt-get update failed"; return 1; }
  $sudo apt-get install -y -q --no-install-recommends "${missing[@]}" >"$DQO_BUILD/apt.log" 2>&1 \
    || { tail -20 "$DQO_BUILD/apt.log"; dqo_log "apt-get install failed (log: $DQO_BUILD/apt.log)"; return 1; }
}

# Whether to build the CUDA ring: nvcc present (it compiles here even without a GPU) unless told off.
dqo_cuda_flag() {
  if [ -n "${DQO_WITH_CUDA:-}" ]; then echo "$DQO_WITH_CUDA"; return; fi
  if command -v nvcc >/dev/null || [ -x /usr/local/cuda/bin/nvcc ]; then echo ON; else echo OFF; fi
}

# Builds the catkin workspace (incremental). Extra arguments go to catkin_make (e.g. a target).
# The package in the workspace: a folder of links to the repository's entries, all but .build
# (and the hidden ones). A link to the repository itself would put the workspace inside its own
# package: rosrun searches the package with `find -L` and walked into .build/ws/src/dqo_map again
# ("File system loop detected", every tool "non-unique" beside its copy in the install space).
dqo_link_package() {
  local pkg="$DQO_WS/src/dqo_map" entry name
  [ -L "$pkg" ] && rm -f "$pkg"
  mkdir -p "$pkg"
  for entry in "$DQO_REPO"/*; do
    name=$(basename "$entry")
    [ "$DQO_REPO/$name" = "$DQO_BUILD" ] && continue
    ln -sfn "$entry" "$pkg/$name"
  done
  for entry in "$pkg"/*; do  # entries the repository no longer has
    [ -L "$entry" ] && [ ! -e "$entry" ] && rm -f "$entry"
  done
  return 0
}

dqo_build_ws() {
  mkdir -p "$DQO_WS/src"
  dqo_link_package
  (cd "$DQO_WS" && catkin_make -j"$DQO_JOBS" \
      -DCMAKE_BUILD_TYPE=Release \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 \
      -DCATKIN_ENABLE_TESTING=ON \
      -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
      -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache \
      -DDQO_WITH_CUDA="$(dqo_cuda_flag)" \
      "$@")
}

# Sources the workspace (devel/setup.bash does not survive `set -u`).
dqo_source_ws() {
  set +u
  # shellcheck disable=SC1091
  source "$DQO_WS/devel/setup.bash"
  set -u
}

# Builds the core alone, the way the GPU machine does (no ROS). Extra arguments go to cmake.
dqo_build_core() {
  local gen=()
  command -v ninja >/dev/null && gen=(-G Ninja)
  [ -f "$DQO_CORE/CMakeCache.txt" ] && gen=()
  cmake -S "$DQO_REPO" -B "$DQO_CORE" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release \
    -DDQO_WITH_ROS=OFF -DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache "$@" >/dev/null \
    && cmake --build "$DQO_CORE" -j"$DQO_JOBS"
}

# Finds a built tool: the catkin devel space first, then the core build.
dqo_find_tool() {
  local t
  for t in "$DQO_WS/devel/lib/dqo_map/$1" "$DQO_CORE/bin/$1"; do
    [ -x "$t" ] && { echo "$t"; return 0; }
  done
  return 1
}
