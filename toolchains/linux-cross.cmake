# SPDX-License-Identifier: MIT
# Shared body of the Debian cross toolchain files: the including file sets CROSS_TRIPLE,
# CMAKE_SYSTEM_PROCESSOR and CROSS_QEMU (the qemu-user binary that runs the tests) first.
# Header-only dependencies (Eigen, xsimd, doctest, stb) come from the host's /usr/include, which the
# cross g++ searches after its own sysroot; binary libraries are only taken from the target's dirs.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_C_COMPILER   ${CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${CROSS_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH /usr/${CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)   # header-only deps are the host's /usr/include
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)   # Eigen3/doctest configs are arch-independent
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${CROSS_TRIPLE}/pkgconfig:/usr/share/pkgconfig")  # never host .pc
# No binfmt_misc on the build machines: test binaries only run through the emulator, and -L points
# qemu at the cross glibc's dynamic loader.
set(CMAKE_CROSSCOMPILING_EMULATOR ${CROSS_QEMU} -L /usr/${CROSS_TRIPLE})
