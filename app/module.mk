# The programs' plumbing: options (Boost.ProgramOptions), logging, progress, exit codes,
# provenance, and what several programs share (detection's options and tiles, a field's
# geometry, gnuplot). Not installed: build/libshapesim-app.a links into the programs only.
APP_SRCS += $(sort $(wildcard app/*.cpp))
