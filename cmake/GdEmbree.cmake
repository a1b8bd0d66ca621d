# Embree 3 (Debian: libembree-dev): BVH builds and rtcCollide for the CPU self-contact broad phase
# (server/sim/contact/broad_phase.cpp). Its config also finds TBB (libtbb-dev, pulled in by it).
find_package(embree 3 REQUIRED)
