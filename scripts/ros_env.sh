# Sourced (not run) by scripts/demo.sh and scripts/test.sh after scripts/setup.sh: the ROS
# environment of the workspace WS (default: ROOT/.build/ws) for what follows.
# shellcheck shell=bash
export PATH="/usr/bin:$PATH"
# A fresh system may have no /etc/hosts (not even "localhost"): use the numeric loopback address
# unless the user chose an address.
if [ -z "${ROS_IP:-}" ] && [ -z "${ROS_HOSTNAME:-}" ]; then export ROS_IP=127.0.0.1; fi
export ROS_MASTER_URI="${ROS_MASTER_URI:-http://127.0.0.1:11311}"
set +u
# shellcheck disable=SC1091
source "${WS:-$ROOT/.build/ws}/devel/setup.bash"
set -u
