# Source files of the input-format readers (included by core/CMakeLists.txt).
set(LIPSYNC_FORMAT_SOURCES
  src/formats/detect.cpp
  src/formats/flite.cpp
  src/formats/json_utterance.cpp
  src/formats/lab.cpp
  src/formats/parse.cpp
  src/formats/pho.cpp
  src/formats/text.cpp
  src/formats/textgrid.cpp
  src/formats/timit.cpp
  src/formats/word_marks.cpp
)
