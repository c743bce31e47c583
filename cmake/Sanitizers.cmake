# Hardening builds (clang only): GEN4D_SANITIZE compiles and links everything with
# AddressSanitizer + UndefinedBehaviorSanitizer; GEN4D_FUZZ adds libFuzzer's coverage
# instrumentation and the fuzz targets of tests/fuzz. jobs/local/run-hardening.sh configures a
# separate build folder with both.
if(NOT (GEN4D_SANITIZE OR GEN4D_FUZZ))
  return()
endif()
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "GEN4D_SANITIZE and GEN4D_FUZZ need clang (-DCMAKE_CXX_COMPILER=clang++)")
endif()

if(GEN4D_SANITIZE)
  # -O1 -g: readable reports at a usable speed; UB aborts (no recovery) so a test or fuzz run
  # fails on the first report.
  # sanitizer-ignorelist.txt: third-party header code left uninstrumented, each entry explained.
  set(GEN4D_SANITIZE_FLAGS -fsanitize=address,undefined -fno-omit-frame-pointer
      -fno-sanitize-recover=undefined
      -fsanitize-ignorelist=${CMAKE_CURRENT_LIST_DIR}/sanitizer-ignorelist.txt)
  add_compile_options($<$<COMPILE_LANGUAGE:C,CXX>:-O1> $<$<COMPILE_LANGUAGE:C,CXX>:-g>
                      "$<$<COMPILE_LANGUAGE:C,CXX>:${GEN4D_SANITIZE_FLAGS}>")
  add_link_options(${GEN4D_SANITIZE_FLAGS})
endif()

if(GEN4D_FUZZ)
  # Coverage feedback from every project library; the fuzz targets link libFuzzer's main.
  add_compile_options($<$<COMPILE_LANGUAGE:C,CXX>:-fsanitize=fuzzer-no-link>)
endif()
