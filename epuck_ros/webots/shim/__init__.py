"""Holds the `controller` module for Webots scripts; `runner` puts this folder (not the package) on sys.path."""
