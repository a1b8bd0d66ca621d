# tinyobjloader 2 (Debian: libtinyobjloader-dev): the one OBJ reader (sim::read_obj, linked to the
# double-precision build tinyobjloader::tinyobjloader_double), used for garments
# made elsewhere and for OBJ point clouds.
find_package(tinyobjloader REQUIRED)
