# The shared library: every share/shapesim/**/*.cpp goes into build/libshapesim.a.
LIB_SRCS += $(sort $(wildcard share/shapesim/*.cpp share/shapesim/app/*.cpp))
