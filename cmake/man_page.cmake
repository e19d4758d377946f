# Script mode: a manual page (roff, gzip -9n) of an executable from its --help, so every installed
# binary has one (Debian policy 12.1).
#   cmake -DEXE=path/linebridge -DNAME=linebridge -DOUTPUT=linebridge.1.gz -P man_page.cmake
execute_process(COMMAND ${EXE} --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${EXE} --help failed")
endif()
execute_process(COMMAND ${EXE} --version OUTPUT_VARIABLE version OUTPUT_STRIP_TRAILING_WHITESPACE)
string(REPLACE "${EXE}" "${NAME}" help "${help}")
string(REGEX MATCH "^[^\n]*" summary "${help}")
string(REGEX REPLACE "^[^:]*: *" "${NAME} \\\\- " summary "${summary}")
string(REPLACE "\\" "\\\\" help "${help}")
string(REGEX REPLACE "\n\\." "\n\\\\&." help "${help}")
file(WRITE ${OUTPUT}.roff
".TH ${NAME} 1 \"\" \"${version}\" \"linebridge\"
.SH NAME
${summary}
.SH SYNOPSIS
.nf
${help}.fi
.SH SEE ALSO
/usr/share/doc/linebridge/README.md
")
execute_process(COMMAND gzip -9nf ${OUTPUT}.roff)
file(RENAME ${OUTPUT}.roff.gz ${OUTPUT})
