# shapesim-table: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-table
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-table := turn a JSON-lines catalogue into a FITS binary table or ECSV, with units
