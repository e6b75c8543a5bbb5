# Fails when the characterisation table of docs/results.md differs from what the code measures now.
execute_process(COMMAND ${HILBENCH} characterise --campaigns ${SOURCE}/configs/campaigns
                OUTPUT_VARIABLE table RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "hilbench characterise failed (${rc})")
endif()
file(READ ${SOURCE}/docs/results.md readme)
string(FIND "${readme}" "<!-- characterise:begin -->\n${table}<!-- characterise:end -->" at)
if(at EQUAL -1)
  message(FATAL_ERROR "docs/results.md's table is stale: run build/bench/hilbench characterise --readme docs/results.md\n${table}")
endif()
