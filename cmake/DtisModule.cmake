# dtis_module(NAME SOURCES ... [PUBLIC deps ...] [PRIVATE deps ...])
# One library target per module (DESIGN.md): dtis_NAME with the alias dtis::NAME, headers in
# NAME/include, installed and exported under the dtis:: namespace.
function(dtis_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC;PRIVATE" ${ARGN})
  add_library(dtis_${name} ${ARG_SOURCES})
  add_library(dtis::${name} ALIAS dtis_${name})
  set_target_properties(dtis_${name} PROPERTIES EXPORT_NAME ${name})
  target_include_directories(dtis_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(dtis_${name} PUBLIC ${ARG_PUBLIC} PRIVATE ${ARG_PRIVATE} dtis_warnings)
  install(TARGETS dtis_${name} EXPORT dtisTargets)
  install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()
