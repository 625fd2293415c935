# Sourced on the GPU machine (scripts/gpu-check, and commands run there by hand): CHOLMOD for
# the deformation graph from Debian's packages carried in .device/cholmod (scripts/fetch-cholmod),
# unpacked into a prefix of its own (the machine's own libgfortran kept when it has one). Sets
# `cholmod_args` (CMake arguments) and LD_LIBRARY_PATH; does nothing without the packages.
cholmod_args=()
if compgen -G ".device/cholmod/*.deb" > /dev/null; then
  cholmod_prefix=$PWD/.device/cholmod/root
  if [ ! -d "$cholmod_prefix" ]; then
    for deb in .device/cholmod/*.deb; do
      case "$deb" in
        *libgfortran5_*|*libquadmath0_*) ldconfig -p | grep -q 'libgfortran.so.5 ' && continue ;;
      esac
      dpkg -x "$deb" "$cholmod_prefix"
    done
  fi
  cholmod_libs=$cholmod_prefix/usr/lib/x86_64-linux-gnu
  for real in "$cholmod_libs"/blas/libblas.so.3 "$cholmod_libs"/lapack/liblapack.so.3; do
    [ -e "$real" ] && ln -sf "$real" "$cholmod_libs/$(basename "$real")"
  done
  export LD_LIBRARY_PATH=$cholmod_libs${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
  cholmod_args=(-DCMAKE_PREFIX_PATH="$cholmod_prefix/usr" -DCMAKE_EXE_LINKER_FLAGS="-Wl,-rpath-link,$cholmod_libs")
fi
