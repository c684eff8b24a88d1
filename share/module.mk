# The library: every share/shapesim/*.cpp goes into build/libshapesim.a (installed; no Boost
# to link, no program code: that is app/ and each program's own folder).
LIB_SRCS += $(sort $(wildcard share/shapesim/*.cpp))
