# PCL 1.13 (Debian: libpcl-dev): PCD/PLY point-cloud I/O and ICP in server/metrics. Debian's
# PCL config loads VTK, whose targets name MPI::MPI_C, so MPI's C component is looked up first
# (the project enables C for this). Kept out of public headers: only .cpp files include PCL.
find_package(MPI COMPONENTS C QUIET)
find_package(PCL 1.10 REQUIRED COMPONENTS common io kdtree search registration)
