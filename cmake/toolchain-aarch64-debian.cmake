# Cross-compiling ccm_agent for arm64 onboard computers (Raspberry Pi 4/5, Jetson, RK3588 ...
# running Debian 12 / Raspberry Pi OS bookworm) on a Debian 12 amd64 machine, with Debian
# multiarch: the arm64 -dev packages install beside the native ones, under
# /usr/lib/aarch64-linux-gnu and /usr/include/aarch64-linux-gnu.
#
#   sudo dpkg --add-architecture arm64 && sudo apt-get update
#   sudo apt-get install g++-aarch64-linux-gnu libfastrtps-dev:arm64 libopencv-dev:arm64 ...
#   deploy/cross-configure-arm64.sh            (docs/deployment.md, "arm64 cross build")
#
# fastddsgen (Java) and the generated code are architecture-independent: the host's is used.
# On Debian 12 the arm64 OpenCV, Ceres, glog and yaml-cpp -dev packages replace the amd64 ones,
# so this only suits a host without them; the working cross build uses an arm64 sysroot
# instead: cmake/toolchain-aarch64-sysroot.cmake, deploy/cross-build-arm64.sh.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CCM_CROSS_TRIPLET aarch64-linux-gnu)

set(CMAKE_C_COMPILER ${CCM_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${CCM_CROSS_TRIPLET}-g++)

# Multiarch: libraries and CMake package configs live under the triplet directories of the
# host's root; headers are shared (/usr/include) plus /usr/include/aarch64-linux-gnu.
set(CMAKE_LIBRARY_ARCHITECTURE ${CCM_CROSS_TRIPLET})
set(CMAKE_FIND_ROOT_PATH /usr/${CCM_CROSS_TRIPLET})
list(APPEND CMAKE_PREFIX_PATH /usr/lib/${CCM_CROSS_TRIPLET}/cmake)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)   # fastddsgen, ccache: the host's
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY BOTH)    # /usr/lib/aarch64-linux-gnu is found via LIBRARY_ARCHITECTURE
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/${CCM_CROSS_TRIPLET}/pkgconfig:/usr/share/pkgconfig)

# Running arm64 test binaries on the build machine needs qemu-user (binfmt); without it
# configure with -DCCM_AGENT_ONLY=ON (no tests) as the script does.
find_program(CCM_QEMU_AARCH64 qemu-aarch64-static qemu-aarch64)
if(CCM_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${CCM_QEMU_AARCH64} -L /usr/${CCM_CROSS_TRIPLET})
endif()
# Debian packages built from this tree are arm64 packages.
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
