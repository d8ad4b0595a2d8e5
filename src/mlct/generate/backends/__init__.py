"""The networks of a model as one backend runs them: text encoder, denoiser (or a whole
sampler), decoder. base.py is the interface the core calls; pytorch.py, onnx/ and
cuda_graphs.py implement it; auto.py picks one for `mlct.load` (generate/load.py)."""
