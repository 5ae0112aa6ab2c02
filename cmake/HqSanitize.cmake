# -DHQ_SANITIZE=address,undefined: every target (ours and the generated IDL code) built with those
# sanitizers; -fno-sanitize-recover=all turns undefined behaviour into a failing test, not a line
# in the log. scripts/test-sanitizers builds the unit tests this way in build-asan/.
set(HQ_SANITIZE "" CACHE STRING "Sanitizers to build with, e.g. address,undefined (empty: none)")
if(HQ_SANITIZE)
  message(STATUS "HaptiQuad: sanitizers ${HQ_SANITIZE}")
  add_compile_options(-fsanitize=${HQ_SANITIZE} -fno-sanitize-recover=all -fno-omit-frame-pointer
                      -g1)
  add_link_options(-fsanitize=${HQ_SANITIZE})
endif()
