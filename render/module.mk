# shapesim-render: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-render
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-render := paint objects into a FITS image as a telescope records them
