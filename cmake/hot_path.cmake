# The simulation's hot path (one control period: RunLoop, the plant's effects, the controller and
# its observer) crosses three libraries. Link-time optimisation lets GCC inline across them, which
# is worth about 7 % of a period (docs/benchmarks.md, "Third round"). Only those libraries carry
# LTO bytecode, in fat objects: everything else (the test programs) links them as ordinary code,
# and only the programs that run campaigns (hilbench, bench_sim) pay for the LTO link. Results
# are the same bits either way: LTO inlines, it does not reassociate or contract (ISO C++ mode,
# -ffp-contract=off).
option(HIL_LTO "Link-time optimise the simulation's hot path in hilbench and bench_sim (GCC, Release)" ON)
set(HIL_LTO_ACTIVE OFF)
if(HIL_LTO AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_BUILD_TYPE STREQUAL "Release" AND NOT HIL_SANITIZE)
  set(HIL_LTO_ACTIVE ON)
endif()

function(hil_hot_path_library target)
  if(HIL_LTO_ACTIVE)
    target_compile_options(${target} PRIVATE -flto=auto -ffat-lto-objects)
  endif()
endfunction()

function(hil_hot_path_program target)
  if(HIL_LTO_ACTIVE)
    target_link_options(${target} PRIVATE -flto=auto)
  endif()
endfunction()
