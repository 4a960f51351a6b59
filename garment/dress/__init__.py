"""Dressing a body in a garment with defaults: `garment dress` and its batch job.

frame.py  the body's units and up axis, the pattern's frame
layout.py a valid start: panels moved apart from each other and from the shrunk body
girth.py  openings and trunk girths: why a garment slid off
job.py    conform, place, sew, settle, check, write (dress())
"""
