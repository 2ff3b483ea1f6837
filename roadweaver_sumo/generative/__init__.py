"""The learned skeleton generator (paper §III-B): a VQ-VAE that turns road fields F into token
grids and a MaskGIT-style transformer that samples token grids conditioned on c.

``vqvae`` and ``maskgit`` are the models and ``training`` their training loops (torch, needed
only to train); ``checkpoint`` the weight files (the trained pair ships in ``weights/`` with
its model card); ``inference`` the models' forward passes in numpy; ``sampling`` turns a
condition and a map extent into a decoded road field of any size, without torch.
"""
