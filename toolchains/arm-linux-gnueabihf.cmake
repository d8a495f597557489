# SPDX-License-Identifier: MIT
# Cross build for 32-bit ARMv7 hard-float Linux with NEON (Raspberry Pi 2/3 in 32-bit mode, Cortex-A
# boards) using Debian's g++-arm-linux-gnueabihf; tests run under qemu-user.
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(CROSS_TRIPLE arm-linux-gnueabihf)
set(CROSS_QEMU qemu-arm)
# Debian's armhf default FPU is vfpv3-d16 without NEON, which leaves xsimd with no arch at all.
# Plain "neon" (not neon-vfpv4) so the binaries also run on Cortex-A9 boards, which lack VFPv4.
# -Wno-psabi silences GCC's notes about the GCC 7.1 ABI change for parameters of vector types.
set(CMAKE_C_FLAGS_INIT "-mfpu=neon -mfloat-abi=hard -Wno-psabi")
set(CMAKE_CXX_FLAGS_INIT "-mfpu=neon -mfloat-abi=hard -Wno-psabi")
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross.cmake)
