#!/usr/bin/env bash
# Installs the system packages lightpath needs on Debian 12, only when missing:
#   - the Vulkan loader and Mesa's lavapipe with ray query (bookworm-backports when the
#     system Mesa is older than 24),
#   - the Khronos validation layer (--validate and tests/validation.rs),
#   - cmake, python3 and a C++ compiler for building shaderc from source,
#   - python3's venv, for the Python package's tests.
# The package mirror is taken from the machine's own apt sources.
set -euo pipefail

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

need=()
command -v cmake >/dev/null || need+=(cmake)
command -v g++ >/dev/null || need+=(g++)
command -v python3 >/dev/null || need+=(python3)
# The Python package's tests build it in a virtual environment.
python3 -c 'import venv, ensurepip' 2>/dev/null || need+=(python3-venv)
command -v ninja >/dev/null || need+=(ninja-build)
dpkg -s libvulkan1 >/dev/null 2>&1 || need+=(libvulkan1)
dpkg -s vulkan-tools >/dev/null 2>&1 || need+=(vulkan-tools)
# The validation layer, for --validate and the validation test.
dpkg -s vulkan-validationlayers >/dev/null 2>&1 || need+=(vulkan-validationlayers)

mesa_version() { dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true; }
mesa_major() { mesa_version | sed -E 's/^([0-9]+:)?([0-9]+).*/\2/'; }

have_new_mesa=0
mv=$(mesa_major)
if [ -n "$mv" ] && [ "$mv" -ge 24 ]; then have_new_mesa=1; fi

if [ ${#need[@]} -eq 0 ] && [ $have_new_mesa = 1 ]; then
  echo "setup-system: everything present (mesa-vulkan-drivers $(mesa_version))"
  exit 0
fi

if ! command -v apt-get >/dev/null; then
  echo "setup-system: missing ${need[*]} and no apt-get; install them by hand" >&2
  exit 1
fi

codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
if [ $have_new_mesa = 0 ] && [ "$codename" = bookworm ]; then
  # Derive the backports source from the mirror the machine already uses.
  if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    mirror=""
    for f in /etc/apt/sources.list.d/*.sources; do
      [ -f "$f" ] || continue
      m=$(awk '/^URIs:/{u=$2} /^Suites:/{ if ($0 ~ /bookworm( |$)/ && u !~ /security/) {print u; exit} }' "$f")
      if [ -n "$m" ]; then mirror=$m; break; fi
    done
    if [ -z "$mirror" ] && [ -f /etc/apt/sources.list ]; then
      mirror=$(awk '$1=="deb" && $3=="bookworm" {print $2; exit}' /etc/apt/sources.list)
    fi
    if [ -z "$mirror" ]; then
      echo "setup-system: could not find a Debian mirror in the apt sources" >&2
      exit 1
    fi
    echo "setup-system: adding bookworm-backports from the machine's mirror"
    printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
      "$mirror" | $SUDO tee /etc/apt/sources.list.d/lightpath-backports.sources >/dev/null
  fi
fi

export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ ${#need[@]} -gt 0 ]; then
  $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"
fi
if [ $have_new_mesa = 0 ]; then
  if [ "$codename" = bookworm ]; then
    $SUDO apt-get install -y -qq --no-install-recommends -t bookworm-backports mesa-vulkan-drivers
  else
    $SUDO apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers
  fi
fi
echo "setup-system: mesa-vulkan-drivers $(mesa_version)"
