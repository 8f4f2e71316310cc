"""Puck physics: free flight (eq. 3.1), Routh rim impacts (eq. 3.2-3.4), fast prediction."""
