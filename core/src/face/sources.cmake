# Source files of the physics face, the target lipsync::face (included by core/CMakeLists.txt).
set(LIPSYNC_FACE_SOURCES
  src/face/face_mesh.cpp
  src/face/face_rig.cpp
  src/face/face_solver.cpp
  src/face/supernodal_factor.cpp
  src/face/face_animation.cpp
  src/face/face_glb.cpp
  src/face/face_raster.cpp
  ${CMAKE_CURRENT_BINARY_DIR}/embedded_face.cpp)
