"""The application: typed scenarios (diagrams/*.yaml), runnable jobs and the `mca-drake`
command."""
