#!/usr/bin/env bash
# The viewer's key test presses keys in a real window on the virtual X display (xdotool, Debian
# package xdotool). Sourced by .ci/run before the cargo tests; fails loudly if it cannot install.
if ! command -v xdotool >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  keys_sudo=""
  [ "$(id -u)" -eq 0 ] || keys_sudo="sudo"
  $keys_sudo apt-get update -qq
  $keys_sudo apt-get install -y -qq xdotool >/dev/null
  command -v xdotool >/dev/null 2>&1 || { echo "error: xdotool did not install" >&2; exit 1; }
fi
