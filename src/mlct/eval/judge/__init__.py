"""The judge: the networks that score generated motions, apart from the measuring around them.

- evaluator.py, networks.py: the text-motion matching evaluator of the standard metrics (Guo et
  al. 2022): its motion and text encoders and how they embed;
- word_vectors.py, learned_words.py: the word/POS vectors its text encoder reads (GloVe, or
  vectors learned for a dataset without GloVe);
- evaluator_dir.py: an evaluator directory (write, load, import the official one);
- train_evaluator.py: `mlct train evaluator`, for any dataset in the standard layout;
- action_classifier.py: the procedural benchmark's action classifier (semantic accuracy).

The judge reads datasets (mlct.data) and never imports the generator: a model under test is
measured by mlct.eval's protocol, which hands the judge motions.
"""
