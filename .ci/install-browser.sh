#!/bin/sh
# Install headless Chromium for the static-HTML viewer test (tests/test_viz_html.py).
# Idempotent: does nothing when /usr/bin/chromium is already present.
set -eu
if [ -x /usr/bin/chromium ]; then
    echo "install-browser: /usr/bin/chromium already present"
    exit 0
fi
SUDO=""
if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update
$SUDO apt-get install -y --no-install-recommends chromium chromium-driver
/usr/bin/chromium --version
