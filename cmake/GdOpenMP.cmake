# The CPU backend runs per-element loops with OpenMP threads.
# The ThreadSanitizer build (GD_SANITIZE=thread, scripts/sanitize tsan) is built without OpenMP:
# Debian's libgomp is not instrumented, so TSan cannot see its barriers and reports the workers'
# reads as races it cannot attribute. There the pragmas are ignored, every loop runs on its
# calling thread (sim/backend/cpu/omp_threads.h reports one thread) and OpenMP::OpenMP_CXX is an
# empty target, so the targets that link it need no change.
if(GD_SANITIZE MATCHES "thread")
  message(STATUS "GD_SANITIZE=thread: building without OpenMP (loops run on their calling thread)")
  add_library(OpenMP::OpenMP_CXX INTERFACE IMPORTED)
  target_compile_options(OpenMP::OpenMP_CXX INTERFACE $<$<COMPILE_LANGUAGE:CXX>:-Wno-unknown-pragmas>)
else()
  find_package(OpenMP REQUIRED COMPONENTS CXX)
endif()
