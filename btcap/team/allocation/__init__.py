"""Who does what: allocation strategies behind one protocol, their registry, and the
auction and consensus allocators.
"""
