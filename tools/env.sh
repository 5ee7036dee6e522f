# Sourced by tools/test and by a shell that runs umbra on the test device: point the Vulkan
# loader at lavapipe only, so tests see the same device everywhere, and give the loader a
# runtime directory.
#   UMBRA_LAVAPIPE=25      (default) Mesa 25's lavapipe: the system's if it is 25 or newer,
#                          else the copy tools/mesa25 unpacked under .deps/mesa25/
#   UMBRA_LAVAPIPE=system  the system's own lavapipe (Mesa 22.3 on Debian 12)
umbra_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
umbra_lvp=${UMBRA_LAVAPIPE:-25}
umbra_system_icd=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
umbra_icd=""
case "$umbra_lvp" in
  system)
    umbra_icd=$umbra_system_icd ;;
  25)
    if [ -f "$umbra_root/.deps/mesa25/ready" ]; then
      umbra_icd=$umbra_root/.deps/mesa25/lvp_icd.json
      export LD_LIBRARY_PATH="$umbra_root/.deps/mesa25/root/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    else
      v=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true); v=${v##*:}
      if [ -n "$v" ] && [ "${v%%.*}" -ge 25 ] 2>/dev/null; then umbra_icd=$umbra_system_icd; fi
    fi ;;
  *)
    echo "UMBRA_LAVAPIPE must be 25 or system, not '$umbra_lvp'" >&2
    return 1 2>/dev/null || exit 1 ;;
esac
if [ -z "$umbra_icd" ] || [ ! -f "$umbra_icd" ]; then
  echo "lavapipe ($umbra_lvp) is missing: run tools/setup" >&2
  return 1 2>/dev/null || exit 1
fi
export VK_ICD_FILENAMES="$umbra_icd"
export VK_DRIVER_FILES="$umbra_icd"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/umbra-xdg-$(id -u)}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
unset umbra_root umbra_lvp umbra_system_icd umbra_icd v
