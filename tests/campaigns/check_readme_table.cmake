# Fails when the README's characterisation table differs from what the code measures now.
execute_process(COMMAND ${HILBENCH} characterise --campaigns ${SOURCE}/configs/campaigns
                OUTPUT_VARIABLE table RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "hilbench characterise failed (${rc})")
endif()
file(READ ${SOURCE}/README.md readme)
string(FIND "${readme}" "<!-- characterise:begin -->\n${table}<!-- characterise:end -->" at)
if(at EQUAL -1)
  message(FATAL_ERROR "README.md's table is stale: run build/bench/hilbench characterise --readme README.md\n${table}")
endif()
