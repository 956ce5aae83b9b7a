#!/usr/bin/env bash
# Install Debian's chromium for the headless browser test of `mocapz view` (tests/test_viewer.py).
# Idempotent and quiet: does nothing when a Chromium is already on the PATH. Never fails the CI run: where
# Chromium cannot be installed (no apt-get, not root, no package), it says so and the browser test skips.
set -u

for b in chromium chromium-browser google-chrome google-chrome-stable; do
  if command -v "$b" >/dev/null 2>&1; then
    exit 0
  fi
done

say() { echo "install-chromium: $*; the browser test of mocapz view will be skipped" >&2; }

if ! command -v apt-get >/dev/null 2>&1; then
  say "no apt-get on this machine"
  exit 0
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO="sudo -n"
  else
    say "not root and no password-less sudo"
    exit 0
  fi
fi

export DEBIAN_FRONTEND=noninteractive
log="$(mktemp)"
if ! { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq chromium; } >"$log" 2>&1; then
  tail -n 5 "$log" >&2
  say "apt-get could not install chromium"
fi
rm -f "$log"
exit 0
