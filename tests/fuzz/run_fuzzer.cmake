# SPDX-License-Identifier: Apache-2.0
# Runs the spec fuzzer for a bounded time on a fresh copy of the seed corpus
# (ctest fuzz.SpecParser; see CMakeLists.txt here).
#   cmake -DFUZZER=bin/spec_fuzzer -DSEED_DIRS="dir;dir" -DDICT=spec.dict
#         -DARTIFACTS=dir -DSECONDS=30 -P run_fuzzer.cmake
# Fails when libFuzzer reports anything (crash, sanitizer report, leak,
# timeout, out of memory) or exits with a non-zero status.
foreach(_v FUZZER SEED_DIRS DICT ARTIFACTS SECONDS)
  if(NOT DEFINED ${_v})
    message(FATAL_ERROR "run_fuzzer.cmake: -D${_v}= is required")
  endif()
endforeach()

# The corpus grows while fuzzing: work on a copy in a temporary directory so
# the sources (and the next run) always start from the same seeds.
if(DEFINED ENV{TMPDIR} AND IS_DIRECTORY "$ENV{TMPDIR}")
  set(_tmp "$ENV{TMPDIR}")
else()
  set(_tmp /tmp)
endif()
string(RANDOM LENGTH 12 _tag)
set(_work "${_tmp}/erg-spec-fuzz-${_tag}")
file(MAKE_DIRECTORY "${_work}/corpus" "${ARTIFACTS}")
set(_seeds "")
foreach(_dir IN LISTS SEED_DIRS)
  file(GLOB _found "${_dir}/*.json")
  list(APPEND _seeds ${_found})
endforeach()
if(NOT _seeds)
  message(FATAL_ERROR "run_fuzzer.cmake: no *.json seeds in ${SEED_DIRS}")
endif()
file(COPY ${_seeds} DESTINATION "${_work}/corpus")
list(LENGTH _seeds _n)
message(STATUS "spec fuzzer: ${SECONDS} s from ${_n} seeds in ${_work}/corpus")

# -error_exitcode / -timeout_exitcode: every finding exits non-zero.
# -rss_limit_mb also caps a single allocation (malloc_limit_mb defaults to it).
# -timeout: one input taking 10 s is a hang (or a quadratic blowup).
execute_process(
  COMMAND "${FUZZER}"
    -max_total_time=${SECONDS}
    -rss_limit_mb=2048
    -timeout=10
    -error_exitcode=77
    -timeout_exitcode=78
    -max_len=8192
    -dict=${DICT}
    -artifact_prefix=${ARTIFACTS}/
    -print_final_stats=1
    "${_work}/corpus"
  RESULT_VARIABLE _rc
  ERROR_VARIABLE _log
  ECHO_ERROR_VARIABLE)
file(REMOVE_RECURSE "${_work}")

# Belt and braces: a sanitizer report that did not stop the run still fails.
if(NOT _rc EQUAL 0 OR _log MATCHES "runtime error:|ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)")
  message(FATAL_ERROR "spec fuzzer failed (exit status ${_rc}); the input that failed is in "
                      "${ARTIFACTS}/ (reproduce: ${FUZZER} FILE)")
endif()
string(REGEX MATCH "stat::number_of_executed_units: *[0-9]+" _units "${_log}")
string(REGEX MATCH "stat::average_exec_per_sec: *[0-9]+" _speed "${_log}")
message(STATUS "spec fuzzer: no finding (${_units}, ${_speed})")
