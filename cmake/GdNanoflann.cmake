# nanoflann (Debian: libnanoflann-dev, header-only): exact L1 and L2 nearest neighbours for the
# sim-to-real metrics (server/metrics/cloud_metrics.cpp).
find_package(nanoflann REQUIRED)
