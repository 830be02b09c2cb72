TOPICS = ("reading",)
