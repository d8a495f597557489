#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# ISA safety of the per-ISA kernel objects, checked with nm (issue 12 item 3).
#   check_isa_symbols.sh NM "obj1;obj2;..."   (the objects of gs_simd; only kernels__<isa>.cpp.o are read)
#
# A kernels__<isa> TU is compiled with that ISA's flags. Any symbol it defines with vague linkage
# (weak, COMDAT, unique) or global binding can be merged by the linker with a same-named copy from
# another TU, so the copy that survives may hold instructions the running CPU lacks. Every such
# symbol must therefore be one that no other ISA can define:
#   - inside gs::simd::isa_<isa> (gs/simd/isa.h: GS_SIMD_ISA_NS), or
#   - an xsimd entity whose name mentions this TU's xsimd arch (xsimd::sse2, xsimd::fma3<xsimd::avx2>,
#     xsimd::avx512bw, xsimd::neon, xsimd::neon64), which only this TU instantiates.
# Allowed besides, because they cannot carry ISA-specific code:
#   - gs::simd::kernel_table_<isa>(): the TU's one exported entry point, a strong symbol whose name
#     already differs per ISA (kernel_table.cpp declares it);
#   - DW.ref.__gxx_personality_v0: a data word holding the address of the C++ EH personality routine
#     (same bytes in every TU, no code);
#   - neon / neon64 only: xsimd::kernel::wrap::* (xsimd_neon.hpp's plain inline wrappers of the NEON
#     intrinsics, emitted even at -O3 because xsimd's dispatch tables take their addresses). NEON is
#     the baseline there (AArch64 always; armhf: the toolchain's -mfpu=neon applies to every TU) and
#     these variant TUs add no flags (simd/CMakeLists.txt), so every copy is built with the same ISA.
# Everything else fails the test: std:: templates (std::min<float>, std::fill, std::exp(float)),
# Eigen, project helpers outside the ISA namespace, xsimd code for another arch, generic xsimd helpers.
# Exit 77 (ctest SKIP_RETURN_CODE) when nm is missing or no variant object is found.
set -u
nm_tool=${1:-}
objects=${2:-}

if [[ -z "$nm_tool" || "$nm_tool" == *NOTFOUND* ]] || ! command -v "$nm_tool" >/dev/null 2>&1; then
  echo "[SKIPPED: no nm tool ('$nm_tool')]"
  exit 77
fi

arch_token() {
  case "$1" in
    sse2) echo 'xsimd::sse2([^0-9a-z_]|$)' ;;
    avx2) echo 'xsimd::fma3<xsimd::avx2>' ;;
    avx512) echo 'xsimd::avx512bw([^0-9a-z_]|$)' ;;
    neon) echo 'xsimd::neon([^0-9a-z_]|$)' ;;
    neon64) echo 'xsimd::neon64([^0-9a-z_]|$)' ;;
    *) return 1 ;;
  esac
}

checked=0
failed=0
IFS=';' read -r -a objs <<<"$objects"
for obj in "${objs[@]}"; do
  base=$(basename "$obj")
  [[ "$base" =~ ^kernels__([a-z0-9]+)\.cpp\.(o|obj)$ ]] || continue
  isa=${BASH_REMATCH[1]}
  if ! token=$(arch_token "$isa"); then
    echo "FAIL $base: unknown ISA '$isa' (add its xsimd arch to $0)"
    failed=1
    continue
  fi
  ns="isa_${isa}"
  # Mangled prefix of anything declared in gs::simd::isa_<isa>, after an optional special-name prefix
  # (guard variables _ZGV, local statics _ZZ, thread-local wrappers _ZTH/_ZTW) and cv-qualifier K.
  own_ns="^_Z(GV|TH|TW|GR)?Z?N(K)?2gs4simd${#ns}${ns}[0-9]"
  if ! raw=$("$nm_tool" --defined-only "$obj"); then
    echo "FAIL $base: $nm_tool could not read it"
    failed=1
    continue
  fi
  demangled=$("$nm_tool" --defined-only -C "$obj")
  bad=0
  total=0
  # Same symbol order in both listings: pair them line by line.
  while IFS=$'\t' read -r rline dline; do
    # "<value> <type> <name>" (value may be absent)
    read -r -a f <<<"$rline"
    if ((${#f[@]} >= 3)); then type=${f[1]}; name=${f[2]}; else type=${f[0]}; name=${f[1]:-}; fi
    dname=${dline#* }; dname=${dname#* }
    # Local symbols (t d b r n ...) never merge across TUs; check global, weak, unique and ifunc ones.
    case "$type" in
      [A-Z] | u | i | v | w) ;;
      *) continue ;;
    esac
    total=$((total + 1))
    if [[ "$name" =~ $own_ns ]]; then continue; fi
    if [[ "$name" =~ ^_ZN(K)?5xsimd && "$dname" =~ $token ]]; then continue; fi
    if [[ "$dname" == "gs::simd::kernel_table_${isa}()" && "$type" == T ]]; then continue; fi
    if [[ "$name" == DW.ref.__gxx_personality_v0 ]]; then continue; fi
    if [[ "$isa" == neon* && "$name" == _ZN5xsimd6kernel4wrap* ]]; then continue; fi
    echo "FAIL $base: $type $dname   [$name]"
    bad=$((bad + 1))
  done < <(paste <(printf '%s\n' "$raw") <(printf '%s\n' "$demangled"))
  checked=$((checked + 1))
  if ((bad > 0)); then
    echo "FAIL $base: $bad of $total global/weak symbols are outside gs::simd::$ns and this ISA's xsimd arch"
    failed=1
  else
    echo "ok   $base: all $total global/weak symbols are in gs::simd::$ns, xsimd ${isa} code or the allow-list"
  fi
done

if ((checked == 0)); then
  echo "[SKIPPED: no kernels__<isa> object among the given objects]"
  exit 77
fi
exit $failed
