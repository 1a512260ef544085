# dtis_module(NAME SOURCES ... [HEADERS ...] [PUBLIC deps ...] [PRIVATE deps ...])
# One library target per module (docs/design.md): dtis_NAME with the alias dtis::NAME, headers in
# NAME/include, exported under the dtis:: namespace. HEADERS (paths under NAME/include) are the
# module's public headers, the ones installed: those the umbrella header dtis/dtis.hpp includes,
# directly or not. The others serve the dtis command, the tests and the benchmarks only.
function(dtis_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;HEADERS;PUBLIC;PRIVATE" ${ARGN})
  add_library(dtis_${name} ${ARG_SOURCES})
  add_library(dtis::${name} ALIAS dtis_${name})
  set_target_properties(dtis_${name} PROPERTIES EXPORT_NAME ${name})
  target_include_directories(dtis_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(dtis_${name} PUBLIC ${ARG_PUBLIC} PRIVATE ${ARG_PRIVATE}
                                                          $<BUILD_INTERFACE:dtis_warnings>)
  install(TARGETS dtis_${name} EXPORT dtisTargets)
  foreach(header ${ARG_HEADERS})
    get_filename_component(dir ${header} DIRECTORY)
    install(FILES include/${header} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/${dir})
  endforeach()
endfunction()
