# Sourced by tools/test and tools/validate: point the Vulkan loader at lavapipe only, so tests
# see the same device everywhere, and give the loader a runtime directory.
lvp_icd=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json 2>/dev/null | head -n 1 || true)
if [ -z "$lvp_icd" ]; then
  echo "lavapipe's ICD file is missing: run tools/setup" >&2
  return 1 2>/dev/null || exit 1
fi
export VK_ICD_FILENAMES="$lvp_icd"
export VK_DRIVER_FILES="$lvp_icd"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/umbra-xdg-$(id -u)}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
