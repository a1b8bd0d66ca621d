# Open Asset Import Library (Debian: libassimp-dev): the mesh files a URDF names for its links'
# collision geometry (STL, OBJ, COLLADA, ...), read in robot mode (server/robot/link_shapes.cpp).
find_package(assimp REQUIRED)
