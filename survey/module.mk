# shapesim-survey: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-survey
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-survey := simulate a survey described in one file: sample and render its field
