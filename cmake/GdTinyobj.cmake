# tinyobjloader 2 (Debian: libtinyobjloader-dev): OBJ import of garments made elsewhere.
find_package(tinyobjloader REQUIRED)
