# Cross-compiling ccm_agent for arm64 (Raspberry Pi 4/5, Jetson, RK3588 ... on Debian 12 /
# Raspberry Pi OS bookworm) on a Debian 12 amd64 machine, against an arm64 sysroot made from
# Debian's own arm64 packages (deploy/make-arm64-sysroot.sh), so nothing arm64 is installed into
# the host. The compiler is Debian's crossbuild-essential-arm64 (aarch64-linux-gnu-g++, its
# libstdc++ and glibc headers); everything else comes from the sysroot.
#
#   deploy/cross-build-arm64.sh OUT_DIR        (docs/deployment.md, "arm64 cross build")
#   cmake -S . -B OUT_DIR/build -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64-sysroot.cmake \
#         -DCCM_ARM64_SYSROOT=OUT_DIR/sysroot -DCCM_AGENT_ONLY=ON
#
# fastddsgen (Java) and the generated code are architecture-independent: the host's is used.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CCM_CROSS_TRIPLET aarch64-linux-gnu)

# The sysroot: a cache variable (-DCCM_ARM64_SYSROOT=...) or the environment (CCM_ARM64_SYSROOT).
if(NOT CCM_ARM64_SYSROOT AND DEFINED ENV{CCM_ARM64_SYSROOT})
  set(CCM_ARM64_SYSROOT "$ENV{CCM_ARM64_SYSROOT}")
endif()
if(NOT CCM_ARM64_SYSROOT OR NOT EXISTS "${CCM_ARM64_SYSROOT}/usr/lib/${CCM_CROSS_TRIPLET}")
  message(FATAL_ERROR "toolchain-aarch64-sysroot: CCM_ARM64_SYSROOT ('${CCM_ARM64_SYSROOT}') is not an "
                      "arm64 sysroot; make one with deploy/make-arm64-sysroot.sh DIR and pass -DCCM_ARM64_SYSROOT=DIR")
endif()
set(CCM_ARM64_SYSROOT "${CCM_ARM64_SYSROOT}" CACHE PATH "arm64 Debian 12 sysroot (deploy/make-arm64-sysroot.sh)")
# try_compile projects re-read this file: hand them the sysroot too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES CCM_ARM64_SYSROOT)

set(CMAKE_SYSROOT "${CCM_ARM64_SYSROOT}")
set(CMAKE_C_COMPILER ${CCM_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${CCM_CROSS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${CCM_CROSS_TRIPLET})

# Libraries, headers and CMake package configs only from the sysroot; programs (fastddsgen,
# ccache) from the host.
set(CMAKE_FIND_ROOT_PATH "${CCM_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${CCM_ARM64_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
    "${CCM_ARM64_SYSROOT}/usr/lib/${CCM_CROSS_TRIPLET}/pkgconfig:${CCM_ARM64_SYSROOT}/usr/share/pkgconfig")

# arm64 programs run on the build machine with qemu-user, the sysroot as their root.
find_program(CCM_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(CCM_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${CCM_QEMU_AARCH64} -L "${CCM_ARM64_SYSROOT}")
endif()
# Debian packages built from this tree are arm64 packages (cmake/CcmInstall.cmake).
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
