"""STANAG 4607 codec, split along its seams (the public API is :mod:`formats.stanag4607`).

* :mod:`.layout`   field tables, existence-mask bits, binary scalings, text fields;
* :mod:`.packet`   packet and segment framing (lazy :func:`iter_packets`, linear :func:`frame`);
* :mod:`.segments` Mission, Job Definition, Free Text, Platform Location, Test and Status bodies;
* :mod:`.dwell`    the Dwell segment: per-mask encoding into packets and vectorised decoding;
* :mod:`.writer`   the meta dict and a run's dwell/detection tables into a packet stream;
* :mod:`.reader`   a packet stream into tables, and those tables back into the same bytes.
"""
