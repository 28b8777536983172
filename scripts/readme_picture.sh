#!/bin/sh
# Regenerate the README's picture: the bundled demo clip on the default arm (wx250s), as a contact sheet drawn
# by the project's own command.  Needs the viz extra: pip install '.[viz]'.
set -eu
cd "$(dirname "$0")/.."
retarget view --moments 6 --png docs/see-it.png
