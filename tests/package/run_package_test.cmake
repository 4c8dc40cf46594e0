# ctest: the installed package works for a project outside this build (docs/packaging.md).
#   cmake -DBUILD_DIR=... -DWORK_DIR=... -DCONSUMER_DIR=... -DVERSION=...
#         [-DPYTHON=... -DPYTHON_DIR=...] -P run_package_test.cmake
# 1. installs BUILD_DIR into the fresh prefix WORK_DIR/prefix (cmake --install --prefix);
# 2. configures and builds CONSUMER_DIR against it (find_package(lmalign VERSION CONFIG) and
#    pkg-config, both of which must report VERSION, the project's);
# 3. runs both executables (each recovers a known transform), a user of the merge component
#    when it is built, and, when PCL is found, a user of
#    the pcl component (find_package(lmalign COMPONENTS pcl), lmalign::pcl);
# 4. runs the installed `lmalign experiment` on a simulated pair: its plots are drawn by the
#    installed script (<prefix>/share/lmalign/scripts), when /usr/bin/python3 has matplotlib;
# 5. with PYTHON: imports the installed Python module from another directory and aligns.
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err
                  WORKING_DIRECTORY ${WORK_DIR})
  message(STATUS "$ ${ARGN}\n${out}${err}")
  set(out "${out}" PARENT_SCOPE)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "package test: failed (exit ${rc}): ${ARGN}")
  endif()
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f lib/cmake/lmalign/lmalignConfig.cmake lib/cmake/lmalign/lmalignConfigVersion.cmake
          lib/pkgconfig/lmalign.pc include/lmalign/registration/registration.hpp bin/lmalign)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "package test: ${f} was not installed")
  endif()
endforeach()
set(ENV{PKG_CONFIG_PATH} ${prefix}/lib/pkgconfig)
run(${CMAKE_COMMAND} -S ${CONSUMER_DIR} -B ${WORK_DIR}/consumer-build -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${prefix} -DLMALIGN_REQUEST_VERSION=${VERSION}
    -DLMALIGN_EXPECT_CONFIG_DIR=${prefix}/lib/cmake/lmalign)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer-build -j 2)
run(${WORK_DIR}/consumer-build/consumer_cmake)
run(${WORK_DIR}/consumer-build/consumer_pkgconfig)
if(EXISTS ${WORK_DIR}/consumer-build/consumer_pcl)
  run(${WORK_DIR}/consumer-build/consumer_pcl)
else()
  message(STATUS "package test: PCL not found: the pcl component is not tested")
endif()
if(EXISTS ${prefix}/include/lmalign/merge/merge.hpp)
  if(NOT EXISTS ${WORK_DIR}/consumer-build/consumer_merge)
    message(FATAL_ERROR "package test: merge headers installed but the merge component not found")
  endif()
  run(${WORK_DIR}/consumer-build/consumer_merge)
else()
  message(STATUS "package test: lmalign::merge not built: the merge component is not tested")
endif()
run(${prefix}/bin/lmalign --version)
if(NOT out STREQUAL "lmalign ${VERSION}\n")
  message(FATAL_ERROR "package test: lmalign --version says '${out}', the project is ${VERSION}")
endif()
foreach(f share/lmalign/scripts/plot_experiment.py share/lmalign/scripts/plot_merge.py)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "package test: ${f} was not installed")
  endif()
endforeach()
execute_process(COMMAND /usr/bin/python3 -c "import matplotlib, numpy" RESULT_VARIABLE no_mpl
                OUTPUT_QUIET ERROR_QUIET)
if(no_mpl)
  message(STATUS "package test: /usr/bin/python3 has no matplotlib: the plots are not tested")
else()
  run(${prefix}/bin/lmalign simulate --scene road --landmarks 200 -o ${WORK_DIR}/sim)
  file(WRITE ${WORK_DIR}/protocol.yaml "source: sim/source.txt\ntarget: sim/target.txt\n"
       "ground_truth: sim/T_target_source.txt\nstrategies: [base]\nexperiments:\n"
       "  - {name: yaws, type: yaw, yaw_deg: [0, 10]}\n")
  run(${prefix}/bin/lmalign experiment ${WORK_DIR}/protocol.yaml -o ${WORK_DIR}/protocol)
  if(NOT out MATCHES "drawn by ${prefix}/share/lmalign/scripts/plot_experiment.py")
    message(FATAL_ERROR "package test: the installed experiment did not plot with the installed "
                        "script:\n${out}")
  endif()
  if(NOT EXISTS ${WORK_DIR}/protocol/plots/yaws_violin.png)
    message(FATAL_ERROR "package test: no plots/yaws_violin.png from the installed lmalign")
  endif()
endif()
if(PYTHON)
  set(ENV{PYTHONPATH} ${prefix}/${PYTHON_DIR})
  run(${PYTHON} ${CMAKE_CURRENT_LIST_DIR}/check_installed_python.py ${prefix})
endif()
