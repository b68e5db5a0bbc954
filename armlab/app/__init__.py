"""The browser lab (viser UI, lessons) and the ``armlab`` command line.

The only package that imports viser.
"""
