raise ImportError("needs a licence for the solver")
