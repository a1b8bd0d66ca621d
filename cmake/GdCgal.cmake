# CGAL 5 (Debian: libcgal-dev, header-only): the 2D constrained Delaunay mesher of the garment
# generator (server/garments/mesher.cpp). GMP/MPFR come with it.
set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL REQUIRED)
