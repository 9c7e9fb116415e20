import numpy as np
from scipy.ndimage import distance_transform_edt
d = np.load("/work/ens/branch.npz")
contact = d["V"] > 0
fail = np.isnan(d["Vc"])
dist = distance_transform_edt(~contact)   # grid cells to the nearest contact node
print("failures:", fail.sum(), "min distance to contact region (cells):", dist[fail].min() if fail.any() else None)
print("contact nodes:", contact.sum(), "of", contact.size)
# consistency: where contact, Vc == V; where separated and Vc valid, Vc should be < 0
sep_ok = (~contact) & ~fail
print("separated nodes with Vc >= 0 (inconsistent):", int((d["Vc"][sep_ok] >= 0).sum()), "of", sep_ok.sum())
print("contact nodes with P != P_c:", int((np.abs(d["P1"] - d["P1c"]) > 1e-6)[contact].sum()))
