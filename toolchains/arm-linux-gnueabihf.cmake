# SPDX-License-Identifier: MIT
# Cross build for 32-bit ARMv7 hard-float Linux with NEON (Raspberry Pi 2/3 in 32-bit mode, Cortex-A
# boards) using Debian's g++-arm-linux-gnueabihf; tests run under qemu-user. Same layout as
# aarch64-linux-gnu.cmake.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(CROSS_TRIPLE arm-linux-gnueabihf)
set(CMAKE_C_COMPILER   ${CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${CROSS_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH /usr/${CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)   # header-only deps are the host's /usr/include
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)   # Eigen3/doctest configs are arch-independent
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${CROSS_TRIPLE}/pkgconfig:/usr/share/pkgconfig")  # never host .pc
# Debian's armhf default FPU is vfpv3-d16 without NEON, which leaves xsimd with no arch at all.
# Plain "neon" (not neon-vfpv4) so the binaries also run on Cortex-A9 boards, which lack VFPv4.
# -Wno-psabi silences GCC's notes about the GCC 7.1 ABI change for parameters of vector types.
set(CMAKE_C_FLAGS_INIT "-mfpu=neon -mfloat-abi=hard -Wno-psabi")
set(CMAKE_CXX_FLAGS_INIT "-mfpu=neon -mfloat-abi=hard -Wno-psabi")
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-arm -L /usr/${CROSS_TRIPLE})
