# The installed package, used the way a project outside this tree uses it (ctest `install_find_package`):
# installs the build into a fresh prefix, configures tools/examples/embed with find_package(volpar) against
# that prefix alone, builds it and runs it (the example checks its own free fall and rest against
# analytic values and exits 1 where they disagree). Called with -DBUILD=<build tree> -DSOURCE=<source tree>
# -DWORK=<scratch folder> -DCXX=<C++ compiler> -DGENERATOR=<CMake generator>.
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})

function(step)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message("${out}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${err}")
  endif()
endfunction()

step(${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/prefix)
foreach(expected lib/cmake/volpar/volparConfig.cmake lib/cmake/volpar/volparConfigVersion.cmake
                 include/volpar/engine/world.hpp include/volpar/engine/core/version.hpp bin/volpar bin/volpar-plot)
  if(NOT EXISTS ${WORK}/prefix/${expected})
    message(FATAL_ERROR "the install has no ${expected}")
  endif()
endforeach()
# only the prefix: CMAKE_FIND_USE_PACKAGE_REGISTRY off, and no path into this build or source tree
step(${CMAKE_COMMAND} -S ${SOURCE}/tools/examples/embed -B ${WORK}/build -G ${GENERATOR}
     -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${WORK}/prefix -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
     -DCMAKE_BUILD_TYPE=Release)
step(${CMAKE_COMMAND} --build ${WORK}/build)
step(${WORK}/build/embed)
# the installed programs run from the prefix: a run, and its plots
step(${WORK}/prefix/bin/volpar run ${SOURCE}/scenes/examples/bounce.yaml --steps 60 -o ${WORK}/bounce.h5)
step(${WORK}/prefix/bin/volpar-plot ${WORK}/bounce.h5 -o ${WORK}/plots)
if(NOT EXISTS ${WORK}/plots/energy.png)
  message(FATAL_ERROR "the installed volpar-plot wrote no ${WORK}/plots/energy.png")
endif()
