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
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
endfunction()

if(VOLPAR_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
