# Compile options for volpar's own targets. Third-party code never sees them.

# volpar_target_options(<target>): warnings as errors, deterministic floating point,
# assertions in every build type but Release.
function(volpar_target_options target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wpedantic -Werror
    -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual
    -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough
    # the same scene and build give the same trajectory bit for bit
    -ffp-contract=off -fno-fast-math)
  target_compile_definitions(${target} PRIVATE
    $<$<NOT:$<CONFIG:Release>>:VOLPAR_ENABLE_ASSERTS=1>)
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
endfunction()

if(VOLPAR_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
