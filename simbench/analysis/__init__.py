"""Analysis on tables: error statistics, published numbers, claim checks, study tables, sim-vs-real statistics.

Functions of data frames and scenarios; they read no results folder (the run
layer does) and draw nothing (the report does).
"""
