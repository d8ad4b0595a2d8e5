"""The onnx backend: the model's networks as ONNX graphs run by ONNX Runtime on the CPU.

bundle.py owns the graph files beside a model and their checks; networks.py runs them;
sampler.py assembles the step loop (and the decoder) into one graph; attention.py fuses the
attentions; decoder_halves.py runs the conv decoder's two halves side by side; compact.py and
int8_pairs.py make the web page's smaller graphs."""
