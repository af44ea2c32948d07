# SPDX-License-Identifier: Apache-2.0
# The comparison peers, PCL 1.13 and Open3D, for tools/bench and `wallar eval` (host only).
# Included once, from the top-level CMakeLists.txt, so every folder sees the result.
# Defines WALLAR_PEERS_FOUND and, when found, the interface target wallar_peer_libs; otherwise
# WALLAR_PEERS_MISSING lists what is missing.
#
# find_package(PCL) fails on Debian 12 (its VTK config wants an MPI target), so PCL's component
# libraries are linked directly; Debian's libpcl-dev installs them with their headers.

set(WALLAR_PEERS_FOUND FALSE)
set(WALLAR_PEERS_MISSING)
if(CMAKE_CROSSCOMPILING)
  set(WALLAR_PEERS_MISSING "a host build (PCL and Open3D are host-only)")
  return()
endif()
find_package(Open3D QUIET)
find_package(OpenMP QUIET COMPONENTS CXX)  # to pin Open3D's thread count
find_path(WALLAR_PCL_INCLUDE pcl/segmentation/sac_segmentation.h PATH_SUFFIXES pcl-1.13)
set(_pcl_libs)
set(_pcl_found TRUE)
foreach(c IN ITEMS common io sample_consensus segmentation search kdtree octree)
  find_library(WALLAR_PCL_${c} NAMES pcl_${c})
  if(WALLAR_PCL_${c})
    list(APPEND _pcl_libs ${WALLAR_PCL_${c}})
  else()
    set(_pcl_found FALSE)
  endif()
endforeach()
find_package(Boost QUIET)  # headers only (pcl/io)

if(NOT Open3D_FOUND)
  list(APPEND WALLAR_PEERS_MISSING "Open3D (libopen3d-dev)")
endif()
if(NOT WALLAR_PCL_INCLUDE OR NOT _pcl_found OR NOT Boost_FOUND)
  list(APPEND WALLAR_PEERS_MISSING "PCL 1.13 (libpcl-dev)")
endif()
if(NOT OpenMP_CXX_FOUND)
  list(APPEND WALLAR_PEERS_MISSING "OpenMP")
endif()
if(WALLAR_PEERS_MISSING)
  return()
endif()
set(WALLAR_PEERS_FOUND TRUE)
add_library(wallar_peer_libs INTERFACE)
target_include_directories(wallar_peer_libs SYSTEM INTERFACE ${WALLAR_PCL_INCLUDE})
target_link_libraries(wallar_peer_libs INTERFACE Open3D::Open3D ${_pcl_libs} Boost::headers
                                                 OpenMP::OpenMP_CXX)
