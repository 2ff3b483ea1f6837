"""The learned skeleton generator (paper §III-B): a VQ-VAE that turns road fields F into token
grids and a MaskGIT-style transformer that samples token grids conditioned on c.

``vqvae`` and ``maskgit`` are the models, ``training`` their training loops, ``checkpoint`` the
weight files (the trained pair ships in ``weights/`` with its model card), ``sampling`` turns a
condition and a map extent into a decoded road field of any size. torch is needed only here.
"""
