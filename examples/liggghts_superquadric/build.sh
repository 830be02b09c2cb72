#!/bin/sh
# Build LIGGGHTS 3.8 with superquadric particles (atom_style superquadric), from Debian's source package.
#
# Debian's `liggghts` binary is compiled without -DSUPERQUADRIC_ACTIVE_FLAG, so `atom_style superquadric`
# stops with "Invalid atom style". The upstream source that Debian ships (liggghts_3.8.0+repack1.orig.tar.xz,
# 6.5 MB) builds with it: the flag (and -DNONSPHERICAL_ACTIVE_FLAG) is what LIGGGHTS's own Makefile.auto adds
# for USE_SUPERQUADRICS = "ON". We build the serial target (MPI stubs, no VTK); the beta function comes from
# boost (libboost-dev) as upstream does when the C++ library lacks std::beta.
#
# Time: about 25 minutes wall with make -j2 under nice on a shared 2-core machine (measured 2026-11-29; the
# template-heavy pair_gran_proxy.cpp alone takes several minutes and ~0.7 GB). Nothing here runs in CI: the dumps
# that run.sh makes are committed under tests/data/liggghts_superquadric/.
#
# Usage: sh build.sh [WORKDIR]   -> WORKDIR/liggghts-sq (default WORKDIR=/tmp/liggghts-sq-build)
# Needs: apt (network to deb.debian.org), g++, make, libboost-dev, xz-utils.
set -eu
WORK=${1:-/tmp/liggghts-sq-build}
mkdir -p "$WORK/lists/partial"
cd "$WORK"
echo "deb-src http://deb.debian.org/debian bookworm main" > src.list
APT="-o Dir::Etc::SourceList=$WORK/src.list -o Dir::Etc::SourceParts=/dev/null -o Dir::State::Lists=$WORK/lists"
if [ ! -f liggghts_3.8.0+repack1.orig.tar.xz ]; then
    # shellcheck disable=SC2086
    apt-get $APT update
    # the debian/ tarball of the source package may be gone from the mirror; only the orig tarball is needed
    # shellcheck disable=SC2086
    apt-get $APT source --download-only liggghts || test -f liggghts_3.8.0+repack1.orig.tar.xz
fi
[ -d LIGGGHTS-PUBLIC-3.8.0 ] || tar xf liggghts_3.8.0+repack1.orig.tar.xz
cd LIGGGHTS-PUBLIC-3.8.0/src
make -C STUBS >/dev/null
# two fixes the upstream 3.8.0 source needs on a current toolchain (Debian's package patches them likewise):
# dump_mesh_vtk.cpp includes VTK without the LAMMPS_VTK guard the other VTK dumps have (we build without VTK),
# utils.h static_casts a temporary stream and finish.cpp compares a pointer with 0, which g++ >= 11 refuses.
rm -f dump_mesh_vtk.cpp dump_mesh_vtk.h
sed -i 's|neighbor->lists\[m\]->numneigh > 0|neighbor->lists[m]->numneigh != NULL|' finish.cpp
sed -i 's|return static_cast< std::ostringstream & >(( std::ostringstream() << std::dec << a ) ).str();|std::ostringstream s; s << std::dec << a; return s.str();|' utils.h
sed -e 's|^LMP_INC =.*|LMP_INC = -DLAMMPS_GZIP -DSUPERQUADRIC_ACTIVE_FLAG -DNONSPHERICAL_ACTIVE_FLAG -DBOOST_INCLUDED|' \
    -e 's|^CCFLAGS =.*|CCFLAGS = -O2 -fPIC -w|' \
    MAKE/Makefile.serial > MAKE/Makefile.sq
nice -n 10 make -k -j2 sq
cp lmp_sq "$WORK/liggghts-sq"
echo "built $WORK/liggghts-sq"
