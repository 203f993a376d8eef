# Compile options for volpar's own targets. Third-party code never sees them.

# volpar_target_options(<target>): warnings as errors, deterministic floating point,
# assertions in every build type but Release.
function(volpar_target_options target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wpedantic -Werror
    -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual
    -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough
    # the same scene and build give the same trajectory bit for bit
    -ffp-contract=off -fno-fast-math
    # GCC 12 at -O3 reports impossible overlapping copies inside libstdc++'s std::string assignment once
    # it is inlined into our code (GCC bug 105329, fixed in 13): not a warning about our code
    $<$<AND:$<CXX_COMPILER_ID:GNU>,$<VERSION_LESS:$<CXX_COMPILER_VERSION>,13>>:-Wno-restrict>)
  target_compile_definitions(${target} PRIVATE
    $<$<NOT:$<CONFIG:Release>>:VOLPAR_ENABLE_ASSERTS=1>)
  # headers are included as "volpar/<module>/..." (the build tree's include/volpar links to the modules, as
  # an install puts them under <prefix>/include/volpar); tests and tools also include their own as
  # "tests/..." and "tools/..."
  target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
                                              $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR})
endfunction()

# VOLPAR_FUZZ (Clang only): every target gets libFuzzer's coverage instrumentation
# (-fsanitize=fuzzer-no-link) on top of the sanitizers; the targets in fuzz/ add -fsanitize=fuzzer,
# which links libFuzzer's driver.
set(VOLPAR_FUZZ_ENABLED OFF)
if(VOLPAR_FUZZ)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    set(VOLPAR_FUZZ_ENABLED ON)
  else()
    message(WARNING "VOLPAR_FUZZ needs Clang (CMAKE_CXX_COMPILER=clang++); "
                    "${CMAKE_CXX_COMPILER_ID} is in use, so the fuzz targets are not built")
  endif()
endif()

if(VOLPAR_SANITIZE OR VOLPAR_FUZZ_ENABLED)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
if(VOLPAR_FUZZ_ENABLED)
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()
